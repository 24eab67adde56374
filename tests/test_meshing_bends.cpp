// meshing/: the bends of rods from meshes (the shortest path over two faces, fits kept no tighter than
// the section), checked against closed forms and three-point circles through the centerlines' points.
#include "meshing/meshing.hpp"
#include "tests/meshing/mesh_fixtures.hpp"
#include "tests/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <vector>

namespace fs = std::filesystem;
using namespace rodfab;
using geometry::Vec3;

namespace {

fs::path scratch(const std::string& name) { return rodfab::test::processScratch("meshing-bends", name); }

// The smallest radius of the circles through three points of `c` 1/1,024 of its parameter range apart
// (|ab| |bd| |ad| / (4 area)): no derivative of rodfab's.
double threePointRadius(const geometry::NurbsCurve& c) {
  constexpr int n = 1024;
  const double h = (c.domainEnd() - c.domainBegin()) / n;
  double smallest = std::numeric_limits<double>::infinity();
  for (int i = 1; i < n; ++i) {
    const double u = c.domainBegin() + i * h;
    const Vec3 a = c.point(u - h), b = c.point(u), d = c.point(u + h);
    const double area = 0.5 * (b - a).cross(d - a).norm();
    if (area > 0) smallest = std::min(smallest, (b - a).norm() * (d - b).norm() * (d - a).norm() / (4 * area));
  }
  return smallest;
}

}  // namespace

namespace {

// The surface of an axis-aligned cube of side `side` centred at the origin, n x n squares a face, each
// split in two: sharp 90-degree creases along its edges.
testing::SimpleMesh subdividedCube(int n, double side) {
  testing::SimpleMesh mesh;
  std::map<std::array<long, 3>, std::uint32_t> index;
  auto vertex = [&](const std::array<long, 3>& k) {  // integer lattice point, in steps of side / n
    auto [it, fresh] = index.try_emplace(k, static_cast<std::uint32_t>(mesh.points.size()));
    if (fresh) mesh.points.emplace_back((k[0] * side) / n - side / 2, (k[1] * side) / n - side / 2, (k[2] * side) / n - side / 2);
    return it->second;
  };
  for (int axis = 0; axis < 3; ++axis)
    for (int high = 0; high < 2; ++high)
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          auto at = [&](int a, int b) {
            std::array<long, 3> k{};
            k[static_cast<std::size_t>(axis)] = high * n, k[static_cast<std::size_t>((axis + 1) % 3)] = a, k[static_cast<std::size_t>((axis + 2) % 3)] = b;
            return vertex(k);
          };
          const std::uint32_t p = at(i, j), q = at(i + 1, j), r = at(i + 1, j + 1), t = at(i, j + 1);
          if (high) mesh.triangles.push_back({p, q, r}), mesh.triangles.push_back({p, r, t});
          else mesh.triangles.push_back({p, r, q}), mesh.triangles.push_back({p, t, r});
        }
  return mesh;
}

// Rods whose smallest three-point radius is below `radius`.
std::size_t rodsTighterThan(const geometry::RodStructure& s, double radius) {
  std::size_t count = 0;
  for (const auto& rod : s.rods) count += threePointRadius(rod.centerline()) < radius;
  return count;
}

}  // namespace

// The smallest radius of curvature the report gives, against second differences of the centerline's
// points (the circle through three points 1/1,024 of a rod apart; no derivative of rodfab's): within
// 2 % (the report samples 17 points a knot span; the three-point circle is exact only as they close up).
TEST_CASE("the report's smallest bend radius and the rods bent tighter than their section", "[meshing]") {
  const fs::path file = scratch("small-ellipsoid.obj");
  testing::writeObj(testing::ellipsoid(16, 3, 2, 1.5), file);
  meshing::MeshRodOptions options;
  options.faces = 100;
  options.section = geometry::Section::circle(1.2);
  const meshing::MeshRods result = meshing::rodsFromMesh(file, options);
  double smallest = std::numeric_limits<double>::infinity();
  for (const auto& rod : result.structure.rods) smallest = std::min(smallest, threePointRadius(rod.centerline()));
  const std::size_t tighter = rodsTighterThan(result.structure, 0.6 * 0.999);
  INFO("report " << result.report.smallestBendRadius << " mm, " << result.report.rodsBentTighterThanSection << " rods; second differences " << smallest << " mm, " << tighter << " rods");
  CHECK(result.report.rodsBentTighterThanSection > 0);
  CHECK(std::abs(smallest / result.report.smallestBendRadius - 1) < 0.02);
  CHECK(tighter + 1 >= result.report.rodsBentTighterThanSection);
  CHECK(tighter <= result.report.rodsBentTighterThanSection + 1);
}


// Rods over a cube's edges: thin rods follow the crease within the tolerance and bend sharply there;
// thick rods keep a fit that bends no tighter than their section and stay off the crease instead.
TEST_CASE("over sharp creases thick rods keep a gentler fit instead of bending tighter than their section", "[meshing]") {
  const fs::path file = scratch("cube.obj");
  testing::writeObj(subdividedCube(8, 20.0), file);  // 768 triangles
  meshing::MeshRodOptions thin, thick;
  thin.faces = thick.faces = 300;
  thin.section = geometry::Section::circle(0.2);
  thick.section = geometry::Section::circle(3.0);
  const meshing::MeshRods hugging = meshing::rodsFromMesh(file, thin), gentle = meshing::rodsFromMesh(file, thick);
  const std::size_t huggingTight = rodsTighterThan(hugging.structure, 1.5), gentleTight = rodsTighterThan(gentle.structure, 1.5);
  const std::size_t huggingSharp = rodsTighterThan(hugging.structure, 0.3), gentleSharp = rodsTighterThan(gentle.structure, 0.3);
  INFO("rods tighter than 1.5 mm: thin " << huggingTight << ", thick " << gentleTight << "; than 0.3 mm: thin " << huggingSharp
       << ", thick " << gentleSharp << "; held off creases: thin " << hugging.report.rodsHeldOffCreases << ", thick " << gentle.report.rodsHeldOffCreases);
  CHECK(hugging.report.rodsHeldOffCreases < gentle.report.rodsHeldOffCreases);
  CHECK(gentleSharp < huggingSharp);  // 20 against 69 (without the rule the two designs are the same)
  CHECK(gentle.report.rodsHeldOffCreases > 0);
  CHECK(gentle.report.rodsHeldOffCreases <= gentle.report.rodsAboveTolerance);
  CHECK(gentleTight <= huggingTight);  // 90 and 90: over a cube's edge every fit of a short rod is tighter than 1.5 mm
  CHECK(gentleTight + 1 >= gentle.report.rodsBentTighterThanSection);
  CHECK(gentleTight <= gentle.report.rodsBentTighterThanSection + 1);
}

namespace {

// A flat sheet (z = 0) of n x n grid points moved by up to `jitter` of the spacing (a fixed LCG, so
// remade exactly), each cell split along alternating diagonals: irregular triangles whose pairs are
// rarely point-symmetric about their shared edge's midpoint.
testing::SimpleMesh jitteredSheet(int n, double spacing, double jitter) {
  testing::SimpleMesh mesh;
  std::uint64_t state = 12345;
  auto uniform = [&] {  // in [-1, 1)
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) / 4503599627370496.0 - 1.0;
  };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) mesh.points.emplace_back((i + jitter * uniform()) * spacing, (j + jitter * uniform()) * spacing, 0.0);
  auto at = [n](int i, int j) { return static_cast<std::uint32_t>(j * n + i); };
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      if ((i + j) % 2 == 0) {
        mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
        mesh.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
      } else {
        mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i, j + 1)});
        mesh.triangles.push_back({at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
      }
    }
  return mesh;
}

Vec3 centroidOf(const testing::SimpleMesh& mesh, const std::array<std::uint32_t, 3>& t) {
  return (mesh.points[t[0]] + mesh.points[t[1]] + mesh.points[t[2]]) / 3.0;
}

// Where the segment p -> q crosses the line through a and b, as a fraction of a -> b (2D, z = 0).
double crossingFraction(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b) {
  const Vec3 d = q - p, e = b - a, w = a - p;
  return (d.x() * w.y() - d.y() * w.x()) / (e.x() * d.y() - e.y() * d.x());
}

// The smallest radius of curvature of the quadratic Bezier curve from p0 over p1 to p2, |B'|^3 / |B' x B''|
// at 4,097 parameters: a closed form at every point, nothing of rodfab's.
double bezierSmallestRadius(const Vec3& p0, const Vec3& p1, const Vec3& p2) {
  double smallest = std::numeric_limits<double>::infinity();
  const Vec3 second = 2.0 * (p0 - 2.0 * p1 + p2);
  for (int i = 0; i <= 4096; ++i) {
    const double t = i / 4096.0;
    const Vec3 first = 2.0 * (1 - t) * (p1 - p0) + 2.0 * t * (p2 - p1);
    smallest = std::min(smallest, std::pow(first.norm(), 3) / first.cross(second).norm());
  }
  return smallest;
}

}  // namespace

// On a plane the shortest path between two faces' centroids over their shared edge is the straight
// segment wherever that segment crosses the edge (the rod keeps a quarter of the edge from its corners).
TEST_CASE("on a flat mesh every rod whose faces allow it is the straight segment between the centroids", "[meshing]") {
  const testing::SimpleMesh sheet = jitteredSheet(12, 3.0, 0.3);  // 242 triangles
  const fs::path file = scratch("sheet.obj");
  testing::writeObj(sheet, file);
  meshing::MeshRodOptions options;
  options.faces = static_cast<int>(sheet.triangles.size());  // kept as it is: no simplification
  options.section = geometry::Section::circle(0.5);
  const meshing::MeshRods result = meshing::rodsFromMesh(file, options);
  REQUIRE(result.report.simplifiedFaces == sheet.triangles.size());
  // Rods by their two end points: each pair of faces sharing an edge, found here from the sheet itself.
  std::map<std::pair<std::array<double, 3>, std::array<double, 3>>, const geometry::Rod*> byEnds;
  for (const auto& rod : result.structure.rods) {
    const Vec3 a = rod.centerline().points().front(), b = rod.centerline().points().back();
    byEnds[{{a.x(), a.y(), a.z()}, {b.x(), b.y(), b.z()}}] = &rod;
    byEnds[{{b.x(), b.y(), b.z()}, {a.x(), a.y(), a.z()}}] = &rod;
  }
  std::size_t straightRods = 0, checked = 0;
  for (std::size_t f = 0; f < sheet.triangles.size(); ++f)
    for (std::size_t g = f + 1; g < sheet.triangles.size(); ++g) {
      std::vector<std::uint32_t> shared;
      for (auto v : sheet.triangles[f])
        if (std::count(sheet.triangles[g].begin(), sheet.triangles[g].end(), v)) shared.push_back(v);
      if (shared.size() != 2) continue;
      const Vec3 c0 = centroidOf(sheet, sheet.triangles[f]), c1 = centroidOf(sheet, sheet.triangles[g]);
      const double t = crossingFraction(c0, c1, sheet.points[shared[0]], sheet.points[shared[1]]);
      ++checked;
      // The rod's nodes are the centroids up to rounding of the projection onto the plane.
      const geometry::Rod* rod = nullptr;
      for (const auto& [ends, r] : byEnds)
        if ((Vec3(ends.first[0], ends.first[1], ends.first[2]) - c0).norm() < 1e-9 &&
            (Vec3(ends.second[0], ends.second[1], ends.second[2]) - c1).norm() < 1e-9) rod = r;
      REQUIRE(rod != nullptr);
      if (t < 0.26 || t > 0.74) continue;
      double offLine = 0;
      const Vec3 along = (c1 - c0).normalized();
      const auto& c = rod->centerline();
      for (int i = 0; i <= 64; ++i) {
        const Vec3 p = c.point(c.domainBegin() + (c.domainEnd() - c.domainBegin()) * i / 64) - c0;
        offLine = std::max(offLine, (p - p.dot(along) * along).norm());
      }
      INFO("faces " << f << ", " << g << ": crossing at " << t << " of the edge");
      CHECK(offLine < 1e-9);
      ++straightRods;
    }
  CHECK(checked == result.structure.rods.size());
  // Most pairs of this sheet (88 %) cross within the edge's middle half; those rods do not bend.
  CHECK(straightRods * 4 >= checked * 3);
  CHECK(result.report.rodsBentTighterThanSection == 0);
}

// Two flat faces whose centroids' straight line crosses their shared edge near its corner (at 1/15 of it):
// the crossing is held a quarter edge in, and the rod turns there by 123 degrees. It turns as the
// quadratic Bezier curve over that crossing does (smallest radius 0.545 mm; the rod 0.64 mm), not in the
// kink of an interpolant through points on the polyline centroid -> crossing -> centroid (0.39 mm here,
// as tight as the points' spacing lets it: finer samples bend it tighter).
TEST_CASE("a rod whose edge crossing is held from a corner turns as gradually as the Bezier curve over it", "[meshing]") {
  testing::SimpleMesh sheet;  // the pair, and a face on each's far edge (the fewest faces asked for is 4)
  sheet.points = {Vec3(0, 0, 0), Vec3(10, 0, 0), Vec3(-8, 3, 0), Vec3(-8, -3, 0), Vec3(12, 6, 0), Vec3(12, -6, 0)};
  sheet.triangles = {{0, 1, 2}, {1, 0, 3}, {1, 4, 2}, {3, 5, 1}};
  const fs::path file = scratch("corner-pair.obj");
  testing::writeObj(sheet, file);
  meshing::MeshRodOptions options;
  options.faces = 4;
  options.section = geometry::Section::circle(0.05);
  const meshing::MeshRods result = meshing::rodsFromMesh(file, options);
  REQUIRE(result.structure.rods.size() == 3);
  const Vec3 c0(2.0 / 3, 1, 0), c1(2.0 / 3, -1, 0), crossing(2.5, 0, 0);  // a quarter of the edge (0,0) -> (10,0)
  const geometry::Rod* rod = nullptr;
  for (const auto& r : result.structure.rods) {
    const auto& points = r.centerline().points();
    const bool ends = std::min((points.front() - c0).norm(), (points.front() - c1).norm()) < 1e-9 &&
                      std::min((points.back() - c0).norm(), (points.back() - c1).norm()) < 1e-9;
    if (ends) rod = &r;
  }
  REQUIRE(rod != nullptr);
  const double expected = bezierSmallestRadius(c0, crossing, c1);
  const double measured = threePointRadius(rod->centerline());
  INFO("Bezier " << expected << " mm, rod " << measured << " mm");
  CHECK(std::abs(expected - 0.545) < 0.001);
  CHECK(measured > 0.8 * expected);  // the interpolant through 4 points of it rounds its apex a little: 0.64 mm
  CHECK(measured < 1.25 * expected);
  CHECK(result.report.rodsBentTighterThanSection == 0);
}

namespace {

// An open surface (u, v) -> point over an nu x nv grid of squares, each split along its diagonal.
testing::SimpleMesh gridSurface(int nu, int nv, const std::function<Vec3(double, double)>& at) {
  testing::SimpleMesh mesh;
  for (int j = 0; j <= nv; ++j)
    for (int i = 0; i <= nu; ++i) mesh.points.push_back(at(double(i) / nu, double(j) / nv));
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const auto a = static_cast<std::uint32_t>(j * (nu + 1) + i), b = a + 1, c = a + static_cast<std::uint32_t>(nu) + 1, d = c + 1;
      mesh.triangles.push_back({a, b, d}), mesh.triangles.push_back({a, d, c});
    }
  return mesh;
}

}  // namespace

// Where every collapse costs nothing (a flat or gently curved region) the simplifier leaves thin
// triangles, and the dual's rods turned sharply between close centroids; the simplified mesh's edges
// between nearly coplanar faces are flipped toward Delaunay. Rods tighter than a 1 mm rod's section
// (three-point circles), before the flips -> after: a flat 50 mm plate at 200 faces 3 -> 0, half a
// cylinder of radius 30 mm at 1000 faces 171 -> 0.
TEST_CASE("thin triangles the simplifier leaves on flat or gently curved regions are flipped, so rods bend gently", "[meshing]") {
  const auto tightRods = [](const testing::SimpleMesh& mesh, const std::string& name, int faces) {
    const fs::path file = scratch(name);
    testing::writeObj(mesh, file);
    meshing::MeshRodOptions options;
    options.faces = faces;
    options.section = geometry::Section::circle(1.0);
    const meshing::MeshRods result = meshing::rodsFromMesh(file, options);
    REQUIRE(result.report.simplifiedFaces <= static_cast<std::size_t>(faces));
    REQUIRE(result.report.simplifiedFaces > static_cast<std::size_t>(faces) * 9 / 10);  // flips keep the count
    return rodsTighterThan(result.structure, 0.5);
  };
  const testing::SimpleMesh plate = gridSurface(40, 40, [](double u, double v) { return Vec3(50 * u, 50 * v, 0); });
  CHECK(tightRods(plate, "plate.obj", 200) == 0);
  const testing::SimpleMesh halfCylinder =
      gridSurface(60, 40, [](double u, double v) { return Vec3(30 * std::sin(3 * (u - 0.5)), 60 * v, 30 * std::cos(3 * (u - 0.5))); });
  CHECK(tightRods(halfCylinder, "half-cylinder.obj", 1000) == 0);
}
