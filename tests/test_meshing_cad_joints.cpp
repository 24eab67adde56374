// rods-from-cad joins curve ends closer than --joint-tolerance, and never moves an end farther than it.
#include "meshing/meshing.hpp"
#include "tests/meshing/cad_test_support.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

using namespace rodfab;
using namespace rodfab::cad_test;

namespace {

// A STEP model of straight lines (polylines #1000, #1003, ...) in curve set #15.
std::string linesModel(const std::vector<std::pair<Vec3, Vec3>>& lines) {
  std::string data, members;
  auto point = [](int id, const Vec3& p) {
    char text[160];  // %E always writes the point a STEP real needs
    std::snprintf(text, sizeof text, "#%d = CARTESIAN_POINT('',(%.17E,%.17E,%.17E));\n", id, p.x(), p.y(), p.z());
    return std::string(text);
  };
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const int id = 1000 + 3 * static_cast<int>(i);
    data += point(id + 1, lines[i].first) + point(id + 2, lines[i].second) + "#" + std::to_string(id) + " = POLYLINE('',(#" +
            std::to_string(id + 1) + ",#" + std::to_string(id + 2) + "));\n";
    members += (i ? ",#" : "#") + std::to_string(id);
  }
  return stepModel("#15 = GEOMETRIC_CURVE_SET('',(" + members + "));\n" + data);
}

// linesModel(lines) written to the scratch file `name`.
fs::path linesFile(const std::string& name, const std::vector<std::pair<Vec3, Vec3>>& lines) {
  const fs::path file = scratch(name);
  std::ofstream(file, std::ios::binary) << linesModel(lines);
  return file;
}

// 50 lines from the origin to a circle of radius 10 mm: their tips 1.26 mm apart.
std::vector<std::pair<Vec3, Vec3>> star() {
  std::vector<std::pair<Vec3, Vec3>> lines;
  for (int i = 0; i < 50; ++i) lines.emplace_back(Vec3::Zero(), 10 * Vec3(std::cos(i * 2 * M_PI / 50), std::sin(i * 2 * M_PI / 50), 0));
  return lines;
}

// The largest distance between a rod's end and the line end it came from.
double largestEndMove(const meshing::CadRods& rods, const std::vector<std::pair<Vec3, Vec3>>& lines) {
  REQUIRE(rods.structure.rods.size() == lines.size());
  double largest = 0;
  for (std::size_t r = 0; r < lines.size(); ++r) {
    const auto& c = rods.structure.rods[r].centerline();
    largest = std::max({largest, (c.point(c.domainBegin()) - lines[r].first).norm(), (c.point(c.domainEnd()) - lines[r].second).norm()});
  }
  return largest;
}

}  // namespace

TEST_CASE("a star whose tips chain within the joint tolerance is refused, not collapsed into a lump", "[meshing][cad]") {
  const fs::path file = linesFile("star.step", star());
  meshing::CadRodOptions wide;
  wide.jointTolerance = 5;  // each tip within 5 mm of its neighbours: a chain 20 mm across
  const std::string error = meshErrorOf(file, [&] { meshing::rodsFromCad(file, wide); });
  CHECK_THAT(error, Catch::Contains("50 curve ends chain into one joint 20 mm across, each within the joint tolerance (5 mm)") &&
                        Catch::Contains("(entity #") && Catch::Contains("are 20 mm apart") && Catch::Contains("give a --joint-tolerance below"));
  // Below the tips' spacing: the centre is one joint and no end moves.
  meshing::CadRodOptions narrow;
  narrow.jointTolerance = 1;
  const meshing::CadRods rods = meshing::rodsFromCad(file, narrow);
  CHECK(rods.report.joints == 1);
  CHECK(rods.report.largestEndMove == 0);
  CHECK(largestEndMove(rods, star()) < 1e-12);
}

TEST_CASE("line starts 0.0009 mm apart in a row are refused at the default tolerance, not moved by 0.045 mm", "[meshing][cad]") {
  std::vector<std::pair<Vec3, Vec3>> lines;
  for (int i = 0; i < 100; ++i) lines.emplace_back(Vec3(0.0009 * i, 0, 0), Vec3(i, 10, 0));
  const std::string error = cadError("row.step", linesModel(lines));
  CHECK_THAT(error, Catch::Contains("100 curve ends chain into one joint 0.0891 mm across, each within the joint tolerance (0.001 mm)") &&
                        Catch::Contains("edge 0 (entity #1000 (POLYLINE))'s start at (0, 0, 0)") &&
                        Catch::Contains("edge 99 (entity #1297 (POLYLINE))'s start at (0.0891, 0, 0)"));
}

TEST_CASE("a chain just wider than the joint tolerance says its width with the digits that show it", "[meshing][cad]") {
  // Starts at x = 0, 0.6 and 1.0004 mm, each within 1 mm of the next: 1.0004 mm across, not "1 mm".
  const std::vector<std::pair<Vec3, Vec3>> lines = {{Vec3(0, 0, 0), Vec3(0, 10, 0)},
                                                     {Vec3(0.6, 0, 0), Vec3(0, 0, 10)},
                                                     {Vec3(1.0004, 0, 0), Vec3(10, 10, 0)}};
  const fs::path file = linesFile("just-wide.step", lines);
  meshing::CadRodOptions options;
  options.jointTolerance = 1;
  const std::string error = meshErrorOf(file, [&] { meshing::rodsFromCad(file, options); });
  CHECK_THAT(error, Catch::Contains("3 curve ends chain into one joint 1.0004 mm across, each within the joint tolerance (1 mm)") &&
                        Catch::Contains("are 1.0004 mm apart"));
}

TEST_CASE("ends within the joint tolerance become one point, each moved by at most the tolerance", "[meshing][cad]") {
  // Three line starts at most 0.0006 mm apart: one joint at their mean.
  const std::vector<std::pair<Vec3, Vec3>> lines = {{Vec3(0, 0, 0), Vec3(10, 0, 0)},
                                                     {Vec3(0.0006, 0, 0), Vec3(0, 10, 0)},
                                                     {Vec3(0.0003, 0.0004, 0), Vec3(0, 0, 10)}};
  const fs::path file = linesFile("near.step", lines);
  const meshing::CadRods rods = meshing::rodsFromCad(file, {});
  CHECK(rods.report.joints == 1);
  const Vec3 mean = (lines[0].first + lines[1].first + lines[2].first) / 3;
  for (const auto& rod : rods.structure.rods) CHECK(rod.centerline().points().front() == mean);
  CHECK(rods.report.largestEndMove <= 0.001);
  CHECK(largestEndMove(rods, lines) <= 0.001);
}
