// geometry/design_file: every bad-input case names the file, the JSON path and what was expected.
#include "geometry/geometry.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <fstream>

using namespace rodfab::geometry;
using nlohmann::json;

namespace {

json validDesign() {
  return json::parse(R"({ "format": "rodfab.design/1", "units": "mm",
    "rods": [ { "name": "edge-0",
      "centerline": { "degree": 3, "knots": [0,0,0,0,1,1,1,1],
                      "points": [[0,0,0],[1,0,0],[2,1,0],[3,1,0]], "weights": [1,1,1,1] },
      "section": { "shape": "circle", "diameter": 1.5 },
      "normal": [0,0,1],
      "modulus": { "degree": 1, "knots": [0,0,0.5,1,1], "values": [8, 120, 40] } } ] })");
}

// Parses `doc` expecting failure; returns the issues.
std::vector<DesignIssue> issuesOf(const std::string& text) {
  try {
    parseDesign(text, "bad.json");
  } catch (const DesignError& e) {
    REQUIRE(e.file() == "bad.json");
    return e.issues();
  }
  FAIL("expected a DesignError");
  return {};
}
std::vector<DesignIssue> issuesOf(const json& doc) { return issuesOf(doc.dump()); }

bool hasIssue(const std::vector<DesignIssue>& issues, const std::string& path, const std::string& fragment) {
  for (const auto& i : issues)
    if (i.path == path && i.message.find(fragment) != std::string::npos) return true;
  return false;
}

#define REQUIRE_ISSUE(doc, path, fragment)                 \
  do {                                                     \
    const auto issues_ = issuesOf(doc);                    \
    INFO(DesignError("bad.json", issues_).what());         \
    REQUIRE(hasIssue(issues_, path, fragment));            \
  } while (0)

}  // namespace

TEST_CASE("The design from the format description reads and evaluates", "[design]") {
  const RodStructure s = parseDesign(validDesign().dump(), "ok.json");
  REQUIRE(s.rods.size() == 1);
  const Rod& r = s.rods[0];
  REQUIRE(r.name() == "edge-0");
  REQUIRE(r.caps() == CapStyle::Round);
  REQUIRE(r.modulus().value(0.5) == Approx(120.0));
  REQUIRE(r.modulus().value(0.25) == Approx(64.0));
  const DesignSummary sum = summarize(s);
  REQUIRE(sum.modulusMin == Approx(8.0));
  REQUIRE(sum.modulusMax == Approx(120.0));
  REQUIRE(sum.circles == 1);
}

TEST_CASE("Design files round-trip through the writer", "[design]") {
  json doc = validDesign();
  doc["rods"].push_back(doc["rods"][0]);
  doc["rods"][1]["name"] = "edge-1";
  doc["rods"][1]["section"] = {{"shape", "rectangle"}, {"width", 2.0}, {"height", 0.5}};
  doc["rods"][1]["caps"] = "flat";
  doc["rods"][1]["modulus"] = 42.5;
  doc["rods"][1].erase("normal");
  doc["rods"][1]["orientation"] = {{"degree", 1}, {"knots", {0, 0, 1, 1}}, {"quaternions", {{1, 0, 0, 0}, {0.9, 0.1, 0, 0}}}};
  const RodStructure a = parseDesign(doc.dump(), "a.json");
  const auto path = std::filesystem::temp_directory_path() / "rodfab_roundtrip.json";
  writeDesign(a, path);
  const RodStructure b = readDesign(path);
  std::filesystem::remove(path);
  REQUIRE(designToJson(a) == designToJson(b));
  REQUIRE(b.rods[1].caps() == CapStyle::Flat);
  REQUIRE(b.rods[1].modulus().isConstant());
  REQUIRE(b.rods[1].orientation().has_value());
  REQUIRE(b.rods[1].section().shape == SectionShape::Rectangle);
}

TEST_CASE("Every kind of bad design is reported with its path", "[design][errors]") {
  SECTION("malformed JSON, with line and column") {
    const auto issues = issuesOf(std::string("{\n  \"format\": \"rodfab.design/1\",\n  \"rods\": [ }"));
    REQUIRE(issues.size() == 1);
    REQUIRE(issues[0].message.find("malformed JSON at line 3") != std::string::npos);
  }
  SECTION("unknown format version") {
    json d = validDesign();
    d["format"] = "rodfab.design/2";
    REQUIRE_ISSUE(d, "format", "unsupported format");
  }
  SECTION("wrong units") {
    json d = validDesign();
    d["units"] = "inch";
    REQUIRE_ISSUE(d, "units", "expected \"mm\"");
  }
  SECTION("knot count inconsistent with points and degree") {
    json d = validDesign();
    d["rods"][0]["centerline"]["knots"] = {0, 0, 0, 1, 1, 1, 1};
    REQUIRE_ISSUE(d, "rods[0].centerline.knots", "expected 8 knots");
  }
  SECTION("too few points for the degree") {
    json d = validDesign();
    d["rods"][0]["centerline"]["points"] = {{0, 0, 0}, {1, 0, 0}};
    REQUIRE_ISSUE(d, "rods[0].centerline.points", "at least 4 control points");
  }
  SECTION("decreasing knots") {
    json d = validDesign();
    d["rods"][0]["centerline"]["knots"] = {0, 0, 0, 0, 1, 1, 0.5, 1};
    REQUIRE_ISSUE(d, "rods[0].centerline.knots[6]", "non-decreasing");
  }
  SECTION("non-finite numbers") {
    std::string text = validDesign().dump();
    text.replace(text.find("[2,1,0]"), 7, "[2,1e999,0]");
    // Named by its path, and the file's other errors are still reported.
    REQUIRE_ISSUE(text, "rods[0].centerline.points[2][1]", "expected a finite number, got 1e999 (beyond the range of a double)");
    text.replace(text.find("\"units\":\"mm\""), 12, "\"units\":\"in\"");
    REQUIRE_ISSUE(text, "units", "expected \"mm\"");
    REQUIRE_ISSUE(text, "rods[0].centerline.points[2][1]", "1e999");
    // Numbers inside strings are left alone.
    json d = validDesign();
    d["description"] = "1e999 \\\" 2e999";
    REQUIRE(parseDesign(d.dump(), "ok.json").rods.size() == 1);
  }
  SECTION("non-numeric coordinates") {
    json d = validDesign();
    d["rods"][0]["centerline"]["points"][1][0] = "one";
    REQUIRE_ISSUE(d, "rods[0].centerline.points[1][0]", "expected a number");
  }
  SECTION("zero and negative weights") {
    json d = validDesign();
    d["rods"][0]["centerline"]["weights"] = {1, 0, -1, 1};
    const auto issues = issuesOf(d);
    REQUIRE(hasIssue(issues, "rods[0].centerline.weights[1]", "> 0"));
    REQUIRE(hasIssue(issues, "rods[0].centerline.weights[2]", "> 0"));
  }
  SECTION("negative diameter") {
    json d = validDesign();
    d["rods"][0]["section"]["diameter"] = -1.5;
    REQUIRE_ISSUE(d, "rods[0].section.diameter", "> 0");
  }
  SECTION("zero modulus, plain and in a spline") {
    json d = validDesign();
    d["rods"][0]["modulus"] = 0;
    REQUIRE_ISSUE(d, "rods[0].modulus", "> 0");
    d = validDesign();
    d["rods"][0]["modulus"]["values"][2] = -3;
    REQUIRE_ISSUE(d, "rods[0].modulus.values[2]", "> 0");
  }
  SECTION("modulus over a different parameter domain") {
    json d = validDesign();
    d["rods"][0]["modulus"]["knots"] = {0, 0, 1, 2, 2};
    REQUIRE_ISSUE(d, "rods[0].modulus.knots", "must equal the centerline's");
  }
  SECTION("degenerate (zero-length) centerline") {
    json d = validDesign();
    d["rods"][0]["centerline"]["points"] = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
    d["rods"][0].erase("normal");
    REQUIRE_ISSUE(d, "rods[0].centerline", "degenerate centerline");
  }
  SECTION("normal parallel to the tangent") {
    json d = validDesign();
    d["rods"][0]["normal"] = {2, 0, 0};
    REQUIRE_ISSUE(d, "rods[0].normal", "parallel");
  }
  SECTION("unknown section shape") {
    json d = validDesign();
    d["rods"][0]["section"] = {{"shape", "hexagon"}, {"diameter", 1}};
    REQUIRE_ISSUE(d, "rods[0].section.shape", "unknown section shape");
  }
  SECTION("unknown keys at every level") {
    json d = validDesign();
    d["colour"] = "red";
    d["rods"][0]["centerline"]["wieghts"] = {1, 1, 1, 1};
    d["rods"][0]["section"]["width"] = 2;
    const auto issues = issuesOf(d);
    REQUIRE(hasIssue(issues, "colour", "unknown key"));
    REQUIRE(hasIssue(issues, "rods[0].centerline.wieghts", "unknown key"));
    REQUIRE(hasIssue(issues, "rods[0].section.width", "unknown key"));
  }
  SECTION("non-circular section without a frame, and both frames at once") {
    json d = validDesign();
    d["rods"][0]["section"] = {{"shape", "ellipse"}, {"width", 2}, {"height", 1}};
    d["rods"][0].erase("normal");
    REQUIRE_ISSUE(d, "rods[0]", "needs a frame");
    d["rods"][0]["normal"] = {0, 0, 1};
    d["rods"][0]["orientation"] = {{"degree", 1}, {"knots", {0, 0, 1, 1}}, {"quaternions", {{1, 0, 0, 0}, {1, 0, 0, 0}}}};
    REQUIRE_ISSUE(d, "rods[0]", "not both");
  }
  SECTION("bad caps, missing fields, empty rods, duplicate names") {
    json d = validDesign();
    d["rods"][0]["caps"] = "pointy";
    REQUIRE_ISSUE(d, "rods[0].caps", "\"round\" or \"flat\"");
    d = validDesign();
    d["rods"][0].erase("modulus");
    REQUIRE_ISSUE(d, "rods[0].modulus", "missing");
    d = validDesign();
    d["rods"] = json::array();
    REQUIRE_ISSUE(d, "rods", "non-empty");
    d = validDesign();
    d["rods"].push_back(d["rods"][0]);
    REQUIRE_ISSUE(d, "rods[1].name", "duplicate rod name");
  }
  SECTION("interior knot repeated past the degree") {
    json d = validDesign();
    d["rods"][0]["centerline"]["degree"] = 1;
    d["rods"][0]["centerline"]["knots"] = {0, 0, 0.5, 0.5, 1, 1};
    REQUIRE_ISSUE(d, "rods[0].centerline.knots[2]", "repeated 2 times");
  }
}

TEST_CASE("All errors of a file are collected, not only the first", "[design][errors]") {
  json d = validDesign();
  d["rods"].push_back(d["rods"][0]);
  d["rods"][0]["section"]["diameter"] = 0;
  d["rods"][1]["name"] = "edge-1";
  d["rods"][1]["centerline"]["knots"][5] = -1;
  d["rods"][1]["modulus"] = "stiff";
  const auto issues = issuesOf(d);
  REQUIRE(issues.size() >= 3);
  REQUIRE(hasIssue(issues, "rods[0].section.diameter", "> 0"));
  REQUIRE(hasIssue(issues, "rods[1].centerline.knots[5]", "non-decreasing"));
  REQUIRE(hasIssue(issues, "rods[1].modulus", "expected a modulus"));
  const std::string all = DesignError("bad.json", issues).what();
  REQUIRE(all.find("bad.json: rods[1].modulus: ") != std::string::npos);
}

TEST_CASE("A missing file is reported with its name", "[design][errors]") {
  try {
    readDesign("/nonexistent/design.json");
    FAIL("expected a DesignError");
  } catch (const DesignError& e) {
    REQUIRE(std::string(e.what()).find("/nonexistent/design.json: cannot open") != std::string::npos);
  }
}

TEST_CASE("The mechanics block reads, round-trips, and is optional", "[design][mechanics]") {
  json d = validDesign();
  REQUIRE_FALSE(parseDesign(d.dump(), "ok.json").mechanics.present);  // old files stay valid
  d["mechanics"] = json::parse(R"({ "poisson_ratio": 0.3, "shear_factor": 0.9, "joint_tolerance": 0.01,
    "joints": [[{"rod": "edge-0", "end": "start"}, {"rod": "edge-0", "end": "end"}]],
    "supports": [{"at": {"rod": "edge-0", "end": "start"}, "type": "clamped", "rotation": [0, 0, 0.1]},
                 {"at": {"point": [3, 1, 0]}, "type": "pinned", "displacement": [0, 0, -1]}],
    "loads": [{"at": {"rod": "edge-0", "end": "end"}, "force": [0, 0, -2], "moment": [0.5, 0, 0]},
              {"at": {"rod": "edge-0", "parameter": 0.25}, "force": [0, 1, 0]}],
    "distributed_loads": [{"rod": "edge-0", "force": [0, 0, -0.01]}],
    "rods": {"edge-0": {"torsion_constant": 0.2, "poisson_ratio": 0.25}},
    "load_steps": 7 })");
  const RodStructure s = parseDesign(d.dump(), "ok.json");
  const MechanicsSpec& m = s.mechanics;
  REQUIRE(m.present);
  CHECK(m.poissonRatio == 0.3);
  CHECK(*m.shearFactor == 0.9);
  CHECK(m.jointTolerance == 0.01);
  CHECK_FALSE(m.inferJoints);
  REQUIRE(m.joints.size() == 1);
  CHECK(m.joints[0][1].end == RodEnd::End);
  REQUIRE(m.supports.size() == 2);
  CHECK(m.supports[0].rotation.z() == 0.1);
  CHECK(m.supports[1].kind == SupportKind::Pinned);
  CHECK(*m.supports[1].at.point == Vec3(3, 1, 0));
  CHECK(m.loads[0].force.z() == -2);
  REQUIRE(m.loads.size() == 2);
  CHECK(*m.loads[1].at.parameter == 0.25);
  CHECK_FALSE(m.loads[0].at.parameter);
  CHECK(m.distributedLoads[0].force.z() == -0.01);
  CHECK(*m.rods[0].torsionConstant == 0.2);
  CHECK(m.loadSteps == 7);
  // The writer keeps every field.
  const RodStructure again = parseDesign(designToJson(s).dump(), "again.json");
  CHECK(designToJson(again) == designToJson(s));
}

TEST_CASE("Bad mechanics blocks are reported with their paths", "[design][mechanics][errors]") {
  auto with = [](const std::string& mechanics) {
    json d = validDesign();
    d["mechanics"] = json::parse(mechanics);
    return d;
  };
  REQUIRE_ISSUE(with(R"({"poisson_ratio": 0.5})"), "mechanics.poisson_ratio", "expected a Poisson ratio in (-1.0, 0.5)");
  REQUIRE_ISSUE(with(R"({"load_steps": 0})"), "mechanics.load_steps", "expected an integer from 1");
  REQUIRE_ISSUE(with(R"({"gravity": 1})"), "mechanics.gravity", "unknown key");
  REQUIRE_ISSUE(with(R"({"supports": [{"at": {"rod": "nope", "end": "start"}, "type": "clamped"}]})"),
                "mechanics.supports[0].at.rod", "no rod is named \"nope\"");
  REQUIRE_ISSUE(with(R"({"supports": [{"at": {"rod": "edge-0", "end": "middle"}, "type": "clamped"}]})"),
                "mechanics.supports[0].at.end", "expected \"start\" or \"end\"");
  REQUIRE_ISSUE(with(R"({"supports": [{"at": {"rod": "edge-0", "end": "end"}, "type": "glued"}]})"),
                "mechanics.supports[0].type", "expected \"clamped\"");
  REQUIRE_ISSUE(with(R"({"supports": [{"at": {"rod": "edge-0", "end": "end"}, "type": "pinned", "rotation": [1, 0, 0]}]})"),
                "mechanics.supports[0].rotation", "a pinned support leaves rotation free");
  REQUIRE_ISSUE(with(R"({"loads": [{"at": {"point": [1, 2]}, "force": [0, 0, 1]}]})"), "mechanics.loads[0].at.point",
                "expected a point in mm as [x, y, z]");
  REQUIRE_ISSUE(with(R"({"loads": [{"at": {"rod": "edge-0", "end": "end"}}]})"), "mechanics.loads[0]",
                "a load needs \"force\"");
  REQUIRE_ISSUE(with(R"({"loads": [{"at": {"rod": "edge-0", "point": [0, 0, 0]}, "force": [0, 0, 1]}]})"),
                "mechanics.loads[0].at", "give either \"rod\" with \"end\" or \"parameter\", or \"point\"");
  REQUIRE_ISSUE(with(R"({"loads": [{"at": {"rod": "edge-0", "end": "end", "parameter": 0.5}, "force": [0, 0, 1]}]})"),
                "mechanics.loads[0].at", "give either \"end\" or \"parameter\", not both");
  REQUIRE_ISSUE(with(R"({"loads": [{"at": {"rod": "edge-0", "parameter": "middle"}, "force": [0, 0, 1]}]})"),
                "mechanics.loads[0].at.parameter", "expected a centerline parameter u");
  REQUIRE_ISSUE(with(R"({"supports": [{"at": {"point": [0, 0, 0], "parameter": 0.5}, "type": "clamped"}]})"),
                "mechanics.supports[0].at.parameter", "\"parameter\" goes with \"rod\", not with \"point\"");
  REQUIRE_ISSUE(with(R"({"joints": [[{"rod": "edge-0", "end": "start"}, {"point": [1, 0, 0]}]]})"), "mechanics.joints[0][1]",
                "not points");
  REQUIRE_ISSUE(with(R"({"joints": [[{"rod": "edge-0", "end": "start"}]]})"), "mechanics.joints[0]",
                "at least two rod ends");
  REQUIRE_ISSUE(with(R"({"rods": {"ghost": {"torsion_constant": 1}}})"), "mechanics.rods.ghost", "no rod is named");
  REQUIRE_ISSUE(with(R"({"rods": {"edge-0": {"torsion_constant": -1}}})"), "mechanics.rods.edge-0.torsion_constant",
                "a torsion constant in mm^4 > 0");
  REQUIRE_ISSUE(with(R"({"distributed_loads": [{"rod": "edge-0", "force": [0, "down", 0]}]})"),
                "mechanics.distributed_loads[0].force[1]", "a number");
}

namespace {

json withLoadCases() {
  json d = validDesign();
  d["mechanics"] = json::parse(R"({ "load_steps": 7,
    "supports": [ { "at": { "rod": "edge-0", "end": "start" }, "type": "clamped" } ],
    "load_cases": [
      { "name": "lift", "supports": [ { "at": { "rod": "edge-0", "end": "start" }, "type": "clamped" } ],
        "loads": [ { "at": { "rod": "edge-0", "end": "end" }, "force": [0, 0, 0.5] } ],
        "target": { "rods": { "edge-0": { "centerline": { "degree": 1, "knots": [0,0,1,1], "points": [[0,0,0],[3,0,1]] },
                                          "normal": [0, 1, 0] } } },
        "weight": 2 },
      { "name": "press", "supports": [ { "at": { "point": [0, 0, 0] }, "type": "pinned" } ],
        "distributed_loads": [ { "rod": "edge-0", "force": [0, 0, -0.01] } ], "load_steps": 3,
        "target": { "design": "target.json" } } ] })");
  d["optimize"] = json::parse(R"({ "position_weight": 2, "curvature_weight": 0.5, "modulus_controls": 6,
    "modulus_degree": 2, "bounds_mpa": [10, 150], "max_iterations": 50, "tolerance": 1e-6 })");
  return d;
}

}  // namespace

TEST_CASE("Load cases, targets and the optimize block read and round-trip", "[design][optimize]") {
  const RodStructure s = parseDesign(withLoadCases().dump(), "ok.json");
  const auto& cases = s.mechanics.loadCases;
  REQUIRE(cases.size() == 2);
  CHECK(cases[0].name == "lift");
  CHECK(cases[0].weight == 2.0);
  CHECK(cases[0].loadSteps == 7);  // the block's
  CHECK(cases[0].loads.size() == 1);
  REQUIRE(cases[0].target.size() == 1);
  CHECK(cases[0].target[0].rod == "edge-0");
  CHECK(cases[0].target[0].centerline.point(1.0).isApprox(Vec3(3, 0, 1)));
  CHECK(cases[0].target[0].referenceNormal.has_value());
  CHECK(cases[1].loadSteps == 3);
  CHECK(cases[1].weight == 1.0);
  CHECK(cases[1].supports[0].kind == SupportKind::Pinned);
  CHECK(cases[1].distributedLoads.size() == 1);
  CHECK(cases[1].targetDesign == "target.json");
  CHECK(cases[1].target.empty());  // parseDesign does not read files; readDesign does
  REQUIRE(s.optimize.present);
  CHECK(s.optimize.modulusControls == 6);
  CHECK(s.optimize.boundsMpa->second == 150.0);
  CHECK(s.optimize.tolerance == 1e-6);

  // Round trip through the writer: the same blocks again.
  const auto dir = std::filesystem::temp_directory_path() / "rodfab_test_load_cases";
  std::filesystem::create_directories(dir);
  writeDesign(s, dir / "target.json");  // this design serves as its own "press" target
  writeDesign(s, dir / "design.json");
  const RodStructure back = readDesign(dir / "design.json");
  REQUIRE(back.mechanics.loadCases.size() == 2);
  CHECK(back.mechanics.loadCases[0].target[0].centerline.points() == cases[0].target[0].centerline.points());
  CHECK(back.mechanics.loadCases[1].targetDesign == "target.json");
  REQUIRE(back.mechanics.loadCases[1].target.size() == 1);  // resolved, relative to the design file
  CHECK(back.mechanics.loadCases[1].target[0].centerline.points() == s.rods[0].centerline().points());
  CHECK(back.optimize.positionWeight == 2.0);
  CHECK(back.optimize.modulusDegree == 2);
  CHECK(designToJson(back) == designToJson(s));
  std::filesystem::remove_all(dir);
}

TEST_CASE("Bad load cases, targets and optimize blocks are reported with their paths", "[design][optimize][errors]") {
  const auto edit = [](const std::function<void(json&)>& change) {
    json d = withLoadCases();
    change(d);
    return d;
  };
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][1]["name"] = "lift"; }), "mechanics.load_cases[1].name",
                "duplicate load case name");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["gravity"] = 1; }), "mechanics.load_cases[0].gravity",
                "unknown key");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0].erase("name"); }), "mechanics.load_cases[0].name", "missing");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["supports"][0]["at"]["rod"] = "nope"; }),
                "mechanics.load_cases[0].supports[0].at.rod", "no rod is named");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][1]["load_steps"] = 0; }), "mechanics.load_cases[1].load_steps",
                "expected an integer from 1");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["weight"] = -1; }), "mechanics.load_cases[0].weight",
                "expected a weight >= 0");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"] = json::array(); }), "mechanics.load_cases", "non-empty array");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["target"] = {{"shape", 1}}; }),
                "mechanics.load_cases[0].target", "expected {\"design\": PATH}");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["target"]["rods"]["edge-9"] = json::object(); }),
                "mechanics.load_cases[0].target.rods.edge-9", "no rod is named");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["target"]["rods"]["edge-0"]["centerline"]["degree"] = 9; }),
                "mechanics.load_cases[0].target.rods.edge-0.centerline.degree", "expected an integer degree");
  REQUIRE_ISSUE(edit([](json& d) { d["optimize"]["bounds_mpa"] = {190, 8}; }), "optimize.bounds_mpa", "lowest modulus below");
  REQUIRE_ISSUE(edit([](json& d) { d["optimize"]["modulus_controls"] = 1; }), "optimize.modulus_controls", "from 2 to 64");
  REQUIRE_ISSUE(edit([](json& d) { d["optimize"]["speed"] = 1; }), "optimize.speed", "unknown key");
  REQUIRE_ISSUE(edit([](json& d) { d["optimize"]["curvature_weight"] = "high"; }), "optimize.curvature_weight", "a weight");

  // A {"design": PATH} target that is missing or names rods this design does not have.
  const auto dir = std::filesystem::temp_directory_path() / "rodfab_test_bad_targets";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "design.json") << withLoadCases().dump();
  try {
    readDesign(dir / "design.json");
    FAIL("expected a DesignError");
  } catch (const DesignError& e) {
    REQUIRE(e.issues().size() == 1);
    CHECK(e.issues()[0].path == "mechanics.load_cases[1].target.design");
    CHECK(e.issues()[0].message.find("target.json") != std::string::npos);
  }
  json other = validDesign();
  other["rods"][0]["name"] = "stranger";
  std::ofstream(dir / "target.json") << other.dump();
  try {
    readDesign(dir / "design.json");
    FAIL("expected a DesignError");
  } catch (const DesignError& e) {
    REQUIRE(e.issues().size() == 1);
    CHECK(e.issues()[0].message.find("\"stranger\" is not in this design") != std::string::npos);
  }
  std::filesystem::remove_all(dir);
}
