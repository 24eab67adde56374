// geometry/design_file: every bad-input case names the file, the JSON path and what was expected.
#include "geometry/design_writer.hpp"
#include "geometry/geometry.hpp"
#include "tests/design_file_fixture.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>

using namespace rodfab::geometry;
using nlohmann::json;
using rodfab::test::hasIssue;
using rodfab::test::validDesign;

namespace {

std::vector<DesignIssue> issuesOf(const std::string& text) { return rodfab::test::designIssues(parseDesign, text); }
std::vector<DesignIssue> issuesOf(const json& doc) { return issuesOf(doc.dump()); }

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

TEST_CASE("Every kind of bad format, units and centerline is reported with its path", "[design][errors]") {
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
    REQUIRE_ISSUE(d, "rods[0].centerline.points", "degree 3 needs at least 4 points, got 2");
  }
  SECTION("more control points than one spline may have: refused before any of them is read") {
    json d = validDesign();
    const std::size_t n = kMaxSplineControls + 1;
    json points = json::array(), knots = json::array({0, 0, 0});
    for (std::size_t i = 0; i < n; ++i) points.push_back({double(i), double(i % 2), 0.0});
    for (std::size_t i = 0; i + 3 <= n; ++i) knots.push_back(double(i) / double(n - 3));
    for (int i = 0; i < 3; ++i) knots.push_back(1.0);
    d["rods"][0]["centerline"] = {{"degree", 3}, {"knots", knots}, {"points", points}};
    REQUIRE_ISSUE(d, "rods[0].centerline.points", "expected at most 16384 points in one spline, got 16385");
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
    // Without an exponent a literal overflows with 310 digits or more; with a capital E as well.
    std::string longInteger = validDesign().dump();
    longInteger.replace(longInteger.find("[2,1,0]"), 7, "[2,-" + std::string(400, '9') + ",0]");
    REQUIRE_ISSUE(longInteger, "rods[0].centerline.points[2][1]", "beyond the range of a double");
    std::string capital = validDesign().dump();
    capital.replace(capital.find("[2,1,0]"), 7, "[2,1,2.5E+400]");
    REQUIRE_ISSUE(capital, "rods[0].centerline.points[2][2]", "beyond the range of a double");
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
}

TEST_CASE("Every kind of bad section, modulus, frame and key is reported with its path", "[design][errors]") {
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

TEST_CASE("Moduli beyond what any material has are refused with their path (below 1 Pa, above 1 TPa)", "[design][errors]") {
  json d = validDesign();
  d["rods"][0]["modulus"] = 1e-300;
  REQUIRE_ISSUE(d, "rods[0].modulus", "at least 1e-06 MPa");
  d = validDesign();
  d["rods"][0]["modulus"]["values"][1] = 2e6;
  REQUIRE_ISSUE(d, "rods[0].modulus.values[1]", "at most 1000000");
}

TEST_CASE("Rod names are 1 to 256 bytes without control characters (they reach the terminal)", "[design][errors]") {
  json d = validDesign();
  d["rods"][0]["name"] = "";
  REQUIRE_ISSUE(d, "rods[0].name", "expected a rod name, not an empty string");
  d["rods"][0]["name"] = std::string(257, 'r');
  REQUIRE_ISSUE(d, "rods[0].name", "expected a rod name of at most 256 bytes, got 257");
  d["rods"][0]["name"] = "arm\x1b[2J";
  REQUIRE_ISSUE(d, "rods[0].name", "expected a rod name without control characters, got 'arm\\x1b[2J'");
  d["rods"][0]["name"] = "arm\xc2\x9b";  // U+009B, the C1 control sequence introducer
  REQUIRE_ISSUE(d, "rods[0].name", "without control characters, got 'arm\\xc2\\x9b'");
  d["rods"][0]["name"] = std::string(256, 'r');  // the longest allowed, and any printable UTF-8
  CHECK(parseDesign(d.dump(), "d.json").rods.size() == 1);
  d["rods"][0]["name"] = "Stab \xc3\xa9\xe2\x82\xac";
  CHECK(parseDesign(d.dump(), "d.json").rods.front().name() == "Stab \xc3\xa9\xe2\x82\xac");
}

TEST_CASE("Knot values and section sizes stay where the solver's arithmetic and the bounding boxes hold", "[design][errors]") {
  SECTION("knot values beyond +-1e12, where the solver's parameter arithmetic is no longer exact; 1e12 itself is read") {
    json d = validDesign();
    d["rods"][0]["centerline"]["knots"] = {0, 0, 0, 0, 1e16, 1e16, 1e16, 1e16};
    REQUIRE_ISSUE(d, "rods[0].centerline.knots[4]", "expected a knot value within +-1e12, got 1e+16");
    d["rods"][0]["centerline"]["knots"] = {-1e300, -1e300, -1e300, -1e300, 0, 0, 0, 0};
    REQUIRE_ISSUE(d, "rods[0].centerline.knots[0]", "expected a knot value within +-1e12");
    d["rods"][0]["centerline"]["knots"] = {0, 0, 0, 0, 1e12, 1e12, 1e12, 1e12};
    d["rods"][0]["modulus"] = {{"degree", 1}, {"knots", {0, 0, 5e11, 1e12, 1e12}}, {"values", {8, 120, 40}}};
    REQUIRE_NOTHROW(parseDesign(d.dump(), "ok.json"));
  }
  SECTION("sections over a kilometre (their stiffness and bounding box overflow); 1e6 mm itself is read") {
    json d = validDesign();
    d["rods"][0]["section"] = {{"shape", "circle"}, {"diameter", 1e300}};
    REQUIRE_ISSUE(d, "rods[0].section.diameter", "expected a diameter in mm of at most 1e6 (a kilometre), got 1e+300");
    d["rods"][0]["section"] = {{"shape", "rectangle"}, {"width", 2e6}, {"height", 1.0}};
    REQUIRE_ISSUE(d, "rods[0].section.width", "at most 1e6");
    d["rods"][0]["section"] = {{"shape", "ellipse"}, {"width", 1.0}, {"height", 1e7}};
    REQUIRE_ISSUE(d, "rods[0].section.height", "at most 1e6");
    d["rods"][0]["section"] = {{"shape", "circle"}, {"diameter", 1e6}};
    REQUIRE_NOTHROW(parseDesign(d.dump(), "ok.json"));
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
  // Up to kMaxListedIssues of them, and one saying the list was cut: 50,000 rods of a bad diameter.
  json many = validDesign();
  many["rods"][0]["section"]["diameter"] = -1;
  for (int i = 1; i < 50000; ++i) many["rods"].push_back(many["rods"][0]), many["rods"][i]["name"] = "rod-" + std::to_string(i);
  const auto listed = issuesOf(many);
  REQUIRE(listed.size() == rodfab::common::kMaxListedIssues + 1);
  CHECK(listed[99].path == "rods[99].section.diameter");
  CHECK_THAT(listed.back().message, Catch::Contains("only the first 100 are listed"));
}

namespace {

// A 0.01 mm rod along a cubic B-spline of 100 spans whose control points lie on a circle of radius 5e8
// mm: followed within the rod's 1e-4 mm, a chord may span 4e-6 rad, so its 6 rad need 1.5 million
// samples, above kMaxSamplesPerRod.
json tooIntricateRod(const std::string& name) {
  std::vector<Vec3> points;
  for (int k = 0; k < 103; ++k) points.emplace_back(5e8 * std::cos(0.06 * k), 5e8 * std::sin(0.06 * k), 0.0);
  std::vector<double> knots(4, 0.0);
  for (int k = 1; k < 100; ++k) knots.push_back(k);
  knots.insert(knots.end(), 4, 100.0);
  const NurbsCurve curve(3, knots, points);
  return json::parse(rodJson(name, curve, Section::circle(0.01), std::nullopt, std::nullopt, CapStyle::Round,
                             BSplineField::constant(100.0, curve.domainBegin(), curve.domainEnd()))
                         .dump());
}

}  // namespace

TEST_CASE("A rod too intricate to sample is reported in the file's order, its rods built on both cores", "[design][errors]") {
  json d = validDesign();
  d["rods"].push_back(tooIntricateRod("huge-1"));
  d["rods"].push_back(validDesign()["rods"][0]);
  d["rods"][2]["name"] = "edge-2";
  d["rods"][2]["modulus"] = "stiff";
  d["rods"].push_back(tooIntricateRod("huge-3"));
  const auto issues = issuesOf(d);
  REQUIRE(issues.size() == 3);
  CHECK(issues[0].path == "rods[1].centerline");
  CHECK_THAT(issues[0].message, Catch::Contains("rod 'huge-1'") && Catch::Contains("polyline samples"));
  CHECK(issues[1].path == "rods[2].modulus");
  CHECK(issues[2].path == "rods[3].centerline");
  d["rods"].erase(3), d["rods"].erase(1);
  d["rods"][1]["modulus"] = 100;  // what is left builds
  CHECK(parseDesign(d.dump(), "ok.json").rods.size() == 2);
}

TEST_CASE("summarizeDesign checks as parseDesign does and says what summarize says of the rods", "[design]") {
  json d = validDesign();
  for (int k = 1; k < 40; ++k) {  // rods of every section and cap, moved apart, on both cores
    json rod = d["rods"][0];
    rod["name"] = "rod-" + std::to_string(k);
    for (json& p : rod["centerline"]["points"]) p[0] = p[0].get<double>() + 3.5 * k, p[2] = p[2].get<double>() - 0.25 * k;
    if (k % 3 == 1) rod["section"] = {{"shape", "rectangle"}, {"width", 2.0}, {"height", 0.5}};
    if (k % 3 == 2) rod["section"] = {{"shape", "ellipse"}, {"width", 1.0 + 0.01 * k}, {"height", 0.5}};
    if (k % 2 == 1) rod["caps"] = "flat";
    if (k % 5 == 0) rod["modulus"] = 10.0 * k;
    d["rods"].push_back(rod);
  }
  const DesignSummary kept = summarize(parseDesign(d.dump(), "a.json")), summarized = summarizeDesign(d.dump(), "a.json");
  CHECK(summarized.rodCount == 40);
  CHECK(summarized.totalLength == kept.totalLength);  // summed in the same order: the same bits
  CHECK(summarized.bounds.min() == kept.bounds.min());
  CHECK(summarized.bounds.max() == kept.bounds.max());
  CHECK(summarized.modulusMin == kept.modulusMin);
  CHECK(summarized.modulusMax == kept.modulusMax);
  CHECK(summarized.modulusMax == 350.0);
  CHECK((summarized.circles == kept.circles && summarized.ellipses == kept.ellipses && summarized.rectangles == kept.rectangles));
  CHECK((summarized.circles == 14 && summarized.ellipses == 13 && summarized.rectangles == 13));
  CHECK((summarized.roundCaps == kept.roundCaps && summarized.flatCaps == kept.flatCaps && summarized.flatCaps == 20));

  d["rods"][7]["modulus"] = "stiff";
  d["rods"].push_back(tooIntricateRod("huge"));
  const auto parsed = issuesOf(d), checked = rodfab::test::designIssues(summarizeDesign, d.dump());
  REQUIRE(parsed.size() == 2);
  REQUIRE(checked.size() == parsed.size());
  for (std::size_t i = 0; i < parsed.size(); ++i) CHECK((checked[i].path == parsed[i].path && checked[i].message == parsed[i].message));
  CHECK(summarize(RodStructure{}).rodCount == 0);
}

TEST_CASE("A missing file is reported with its name", "[design][errors]") {
  try {
    readDesign("/nonexistent/design.json");
    FAIL("expected a DesignError");
  } catch (const DesignError& e) {
    REQUIRE(std::string(e.what()).find("/nonexistent/design.json: cannot open") != std::string::npos);
  }
}

TEST_CASE("The rods reader leaves the mechanics and optimize blocks to mechanics/", "[design]") {
  json d = validDesign();
  d["mechanics"] = {{"load_steps", 0}, {"supports", "none"}};  // both wrong, and not geometry's to say
  d["optimize"] = {{"max_iterations", -1}};
  const RodStructure s = parseDesign(d.dump(), "ok.json");
  REQUIRE(s.rods.size() == 1);
  CHECK(designToJson(s) == designToJson(parseDesign(validDesign().dump(), "ok.json")));
  d["gravity"] = 9.81;  // the format's other keys are still checked
  REQUIRE_ISSUE(d, "gravity", "unknown key (expected one of: description, format, mechanics, metadata, optimize, rods, units, written_by)");
}
