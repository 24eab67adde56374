// mechanics/mechanics_file: the "mechanics" and "optimize" blocks of a design file read, round-trip
// and report every bad input at its JSON path, after the rods' issues (one read, one list).
#include "mechanics/mechanics_file.hpp"
#include "tests/design_file_fixture.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <fstream>

using namespace rodfab::mechanics;
using nlohmann::json;
using rodfab::geometry::DesignError;
using rodfab::geometry::DesignIssue;
using rodfab::geometry::Vec3;
using rodfab::test::hasIssue;
using rodfab::test::validDesign;

namespace {

std::vector<DesignIssue> issuesOf(const std::string& text) { return rodfab::test::designIssues(parseDesign, text); }
std::vector<DesignIssue> issuesOf(const json& doc) { return issuesOf(doc.dump()); }

}  // namespace

TEST_CASE("Issues of the rods and of the mechanics and optimize blocks come in one list, in file order", "[design][mechanics][errors]") {
  json d = validDesign();
  d["rods"][0]["section"]["diameter"] = 0;
  d["mechanics"] = {{"load_steps", 0}};
  d["optimize"] = {{"max_iterations", -1}};
  const auto issues = issuesOf(d);
  REQUIRE(issues.size() == 3);
  CHECK(issues[0].path == "rods[0].section.diameter");
  CHECK(issues[1].path == "mechanics.load_steps");
  CHECK(issues[2].path == "optimize.max_iterations");
  // A design without rods has no names to check the mechanics block against: it is not read.
  d["rods"] = json::array();
  CHECK_FALSE(hasIssue(issuesOf(d), "mechanics.load_steps", "expected an integer"));
}

TEST_CASE("The mechanics block reads, round-trips, and is optional", "[design][mechanics]") {
  json d = validDesign();
  REQUIRE_FALSE(parseDesign(d.dump(), "ok.json").mechanics.present);  // old files stay valid
  d["mechanics"] = json::parse(R"({ "poisson_ratio": 0.3, "shear_factor": 0.9, "joint_tolerance": 0.01,
    "joints": [[{"rod": "edge-0", "end": "start"}, {"rod": "edge-0", "end": "end"}]],
    "supports": [{"at": {"rod": "edge-0", "end": "start"}, "type": "clamped", "rotation": [0, 0, 0.1]},
                 {"at": {"point": [3, 1, 0]}, "type": "pinned", "displacement": [0, 0, -1]}],
    "loads": [{"at": {"rod": "edge-0", "end": "end"}, "force": [0, 0, -2], "moment": [0.5, 0, 0]},
              {"at": {"rod": "edge-0", "parameter": 0.25}, "force": [0, 1, 0], "follower": true}],
    "distributed_loads": [{"rod": "edge-0", "force": [0, 0, -0.01]}],
    "rods": {"edge-0": {"torsion_constant": 0.2, "poisson_ratio": 0.25}},
    "load_steps": 7 })");
  const Design s = parseDesign(d.dump(), "ok.json");
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
  CHECK_FALSE(m.loads[0].follower);  // dead by default, as in files from before follower loads
  CHECK(m.loads[1].follower);
  CHECK(m.distributedLoads[0].force.z() == -0.01);
  CHECK(*m.rods[0].torsionConstant == 0.2);
  CHECK(m.loadSteps == 7);
  // The writer keeps every field.
  const Design again = parseDesign(designToJson(s).dump(), "again.json");
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
  REQUIRE_ISSUE(with(R"({"load_steps": 1001})"), "mechanics.load_steps", "expected an integer from 1 to 1000, got 1001");
  CHECK_NOTHROW(parseDesign(with(R"({"load_steps": 1000})").dump(), "ok.json"));
  REQUIRE_ISSUE(with(R"({"gravity": 1})"), "mechanics.gravity", "unknown key");
  REQUIRE_ISSUE(with(R"({"supports": [{"at": {"rod": "nope", "end": "start"}, "type": "clamped"}]})"),
                "mechanics.supports[0].at.rod", "no rod is named 'nope'");
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
  REQUIRE_ISSUE(with(R"({"loads": [{"at": {"rod": "edge-0", "end": "end"}, "force": [0, 0, 1], "follower": "yes"}]})"),
                "mechanics.loads[0].follower", "expected true (the load turns with the cross-section) or false");
  REQUIRE_ISSUE(with(R"({"load_cases": [{"name": "a", "supports": [{"at": {"rod": "edge-0", "end": "start"}, "type": "clamped"}],
                "loads": [{"at": {"rod": "edge-0", "end": "end"}, "force": [0, 0, 1], "follower": 1}],
                "target": {"design": "t.json"}}]})"),
                "mechanics.load_cases[0].loads[0].follower", "expected true");
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

TEST_CASE("A target design's file is relative to the design that names it, unless absolute", "[design][optimize]") {
  LoadCase lc;
  CHECK(targetDesignFile(lc, "/a/b/design.json").empty());  // an inline target names no file
  lc.targetDesign = "shapes/target.json";
  CHECK(targetDesignFile(lc, "/a/b/design.json") == std::filesystem::path("/a/b/shapes/target.json"));
  CHECK(targetDesignFile(lc, "design.json") == std::filesystem::path("shapes/target.json"));
  lc.targetDesign = "../target.json";
  CHECK(targetDesignFile(lc, "/a/b/design.json").lexically_normal() == std::filesystem::path("/a/target.json"));
  lc.targetDesign = "/elsewhere/target.json";
  CHECK(targetDesignFile(lc, "/a/b/design.json") == std::filesystem::path("/elsewhere/target.json"));
}

TEST_CASE("Load cases, targets and the optimize block read and round-trip", "[design][optimize]") {
  const Design s = parseDesign(withLoadCases().dump(), "ok.json");
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
  const Design back = readDesign(dir / "design.json");
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

TEST_CASE("Load cases whose weights are all 0 are refused: the objective would be empty", "[design][optimize][errors]") {
  json d = withLoadCases();
  for (json& c : d["mechanics"]["load_cases"]) c["weight"] = 0;
  REQUIRE_ISSUE(d, "mechanics.load_cases", "every load case's weight is 0: the objective would be empty");
  d["mechanics"]["load_cases"][0]["weight"] = 1e-6;
  REQUIRE_NOTHROW(parseDesign(d.dump(), "ok.json"));
}

TEST_CASE("Bad load cases, targets and optimize blocks are reported with their paths", "[design][optimize][errors]") {
  const auto edit = [](const std::function<void(json&)>& change) {
    json d = withLoadCases();
    change(d);
    return d;
  };
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][1]["name"] = "lift"; }), "mechanics.load_cases[1].name",
                "duplicate load case name");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][1]["name"] = "lift\x07"; }), "mechanics.load_cases[1].name",
                "expected a case name without control characters, got 'lift\\x07'");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][1]["name"] = ""; }), "mechanics.load_cases[1].name",
                "expected a case name, not an empty string");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["gravity"] = 1; }), "mechanics.load_cases[0].gravity",
                "unknown key");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0].erase("name"); }), "mechanics.load_cases[0].name", "missing");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["supports"][0]["at"]["rod"] = "nope"; }),
                "mechanics.load_cases[0].supports[0].at.rod", "no rod is named");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][1]["load_steps"] = 0; }), "mechanics.load_cases[1].load_steps",
                "expected an integer from 1");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["weight"] = -1; }), "mechanics.load_cases[0].weight",
                "expected a weight of 0 or from 1e-06 to 1e+06");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["weight"] = 5e-324; }), "mechanics.load_cases[0].weight",
                "expected a weight of 0 or from 1e-06 to 1e+06, got 5e-324");
  REQUIRE_ISSUE(edit([](json& d) { d["optimize"]["position_weight"] = 1e308; }), "optimize.position_weight", "from 1e-06 to 1e+06");
  REQUIRE_ISSUE(edit([](json& d) { d["optimize"]["position_weight"] = 0, d["optimize"]["curvature_weight"] = 0; }), "optimize",
                "both 0: the objective would be empty");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"] = json::array(); }), "mechanics.load_cases", "non-empty array");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["target"] = {{"shape", 1}}; }),
                "mechanics.load_cases[0].target", "expected {\"design\": PATH}");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["target"]["rods"]["edge-9"] = json::object(); }),
                "mechanics.load_cases[0].target.rods.edge-9", "no rod is named");
  REQUIRE_ISSUE(edit([](json& d) { d["mechanics"]["load_cases"][0]["target"]["rods"]["edge-0"]["centerline"]["degree"] = 9; }),
                "mechanics.load_cases[0].target.rods.edge-0.centerline.degree", "expected an integer degree");
  // A target's normal is checked as a rod's: not along the centerline's start, any magnitude (a normal
  // of 1e-320 failed inside the optimizer as "parallel", one along the tangent passed the reader).
  REQUIRE_ISSUE(edit([](json& d) {
                  auto& rod = d["mechanics"]["load_cases"][0]["target"]["rods"]["edge-0"];
                  const auto& p = rod["centerline"]["points"];
                  rod["normal"] = {p[1][0].get<double>() - p[0][0].get<double>(), p[1][1].get<double>() - p[0][1].get<double>(),
                                   p[1][2].get<double>() - p[0][2].get<double>()};
                }),
                "mechanics.load_cases[0].target.rods.edge-0.normal", "is parallel to the centerline's tangent");
  REQUIRE_ISSUE(edit([](json& d) { d["optimize"]["bounds_mpa"] = {190, 8}; }), "optimize.bounds_mpa", "lowest modulus below");
  REQUIRE_ISSUE(edit([](json& d) { d["optimize"]["modulus_controls"] = 1; }), "optimize.modulus_controls", "from 2 to 64");
  REQUIRE_ISSUE(edit([](json& d) { d["optimize"]["speed"] = 1; }), "optimize.speed", "unknown key");
  REQUIRE_ISSUE(edit([](json& d) { d["optimize"]["curvature_weight"] = "high"; }), "optimize.curvature_weight", "a weight");

  // A {"design": PATH} target that is missing or names rods this design does not have: the same
  // issues from readDesign and from checkDesign (which keeps no rods).
  const auto dir = std::filesystem::temp_directory_path() / "rodfab_test_bad_targets";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "design.json") << withLoadCases().dump();
  // Each reader's issues, checked to be one issue at the target's path.
  const auto issueOfEach = [&dir] {
    std::vector<std::string> messages;
    for (const auto& read : std::vector<std::function<void()>>{[&] { readDesign(dir / "design.json"); }, [&] { checkDesign(dir / "design.json"); }}) {
      try {
        read();
        FAIL("expected a DesignError");
      } catch (const DesignError& e) {
        REQUIRE(e.issues().size() == 1);
        CHECK(e.issues()[0].path == "mechanics.load_cases[1].target.design");
        messages.push_back(e.issues()[0].message);
      }
    }
    return messages;
  };
  for (const std::string& message : issueOfEach()) CHECK(message.find("target.json") != std::string::npos);
  json other = validDesign();
  other["rods"][0]["name"] = "stranger";
  std::ofstream(dir / "target.json") << other.dump();
  for (const std::string& message : issueOfEach()) CHECK(message.find("\"stranger\" is not in this design") != std::string::npos);
  std::ofstream(dir / "target.json") << validDesign().dump();  // names the design's rod: both read it
  const rodfab::geometry::DesignSummary kept = rodfab::geometry::summarize(readDesign(dir / "design.json")),
                                        checked = checkDesign(dir / "design.json");
  CHECK((checked.rodCount == kept.rodCount && checked.totalLength == kept.totalLength && checked.bounds.min() == kept.bounds.min() &&
         checked.bounds.max() == kept.bounds.max() && checked.modulusMin == kept.modulusMin && checked.modulusMax == kept.modulusMax));
  std::filesystem::remove_all(dir);
}
