// voxel/: rasterization against analytic volumes, the exact per-voxel test, and itself (threads, bands).
#include "voxel/voxel.hpp"

#include "examples/example_designs.hpp"
#include "geometry/geometry.hpp"

#include <catch2/catch.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <mutex>
#include <filesystem>
#include <numbers>
#include <random>
#include <unordered_set>

using namespace rodfab;
using geometry::BSplineField;
using geometry::CapStyle;
using geometry::NurbsCurve;
using geometry::Rod;
using geometry::RodStructure;
using geometry::Section;
using geometry::Vec3;
using voxel::PrinterGrid;

namespace {

// The Connex3 profile's voxel (600 x 300 dpi, 30 um layers), which the numbers in these tests assume.
const openvdb::Vec3d kTestVoxel(0.0423, 0.0846, 0.030);

constexpr double kPi = std::numbers::pi;

NurbsCurve line(const Vec3& a, const Vec3& b) { return NurbsCurve(1, {0, 0, 1, 1}, {a, b}); }

// Circular arc of radius R about c in the xy-plane from angle 0 to `angle` (<= 2 pi), exact
// rational quadratic with one span per quarter turn (at most).
NurbsCurve arc(double R, double angle, const Vec3& c = Vec3::Zero()) {
  const int spans = std::max(1, static_cast<int>(std::ceil(angle / (0.5 * kPi) - 1e-9)));
  const double step = angle / spans, w = std::cos(0.5 * step);
  std::vector<Vec3> pts;
  std::vector<double> weights, knots = {0, 0, 0};
  for (int s = 0; s < spans; ++s) {
    const double a0 = s * step, am = a0 + 0.5 * step;
    if (s == 0) pts.push_back(c + R * Vec3(std::cos(a0), std::sin(a0), 0)), weights.push_back(1);
    pts.push_back(c + (R / w) * Vec3(std::cos(am), std::sin(am), 0));
    weights.push_back(w);
    pts.push_back(c + R * Vec3(std::cos(a0 + step), std::sin(a0 + step), 0));
    weights.push_back(1);
    if (s + 1 < spans) knots.insert(knots.end(), {double(s + 1) / spans, double(s + 1) / spans});
  }
  knots.insert(knots.end(), {1, 1, 1});
  return NurbsCurve(2, knots, pts, weights);
}

// A cubic B-spline with control points on a helix (close to, not exactly, a helix).
NurbsCurve helix(double radius, double pitch, double turns, int pointsPerTurn = 12) {
  const int n = static_cast<int>(turns * pointsPerTurn) + 1;
  std::vector<Vec3> pts;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * kPi * i / pointsPerTurn;
    pts.emplace_back(radius * std::cos(a), radius * std::sin(a), pitch * a / (2 * kPi));
  }
  std::vector<double> knots(4, 0.0);
  for (int i = 1; i < n - 3; ++i) knots.push_back(static_cast<double>(i) / (n - 3));
  knots.insert(knots.end(), 4, 1.0);
  return NurbsCurve(3, knots, pts);
}

Rod circularRod(NurbsCurve c, double radius, CapStyle caps, BSplineField e = BSplineField::constant(50, 0, 1)) {
  return Rod("rod", std::move(c), Section::circle(2 * radius), std::nullopt, std::nullopt, caps, std::move(e));
}

RodStructure design(std::vector<Rod> rods) { return RodStructure{"test", std::move(rods)}; }

double occupiedVolume(const voxel::Rasterization& r, const PrinterGrid& g) {
  return double(r.grid->activeVoxelCount()) * g.voxelVolume();
}

Vec3 world(const PrinterGrid& g, const openvdb::Coord& c) {
  const openvdb::Vec3d p = g.worldPoint(c);
  return {p.x(), p.y(), p.z()};
}

// Number of face-connected components of the active voxels.
int componentCount(const openvdb::FloatGrid& grid) {
  auto key = [](const openvdb::Coord& c) {
    return (std::uint64_t(std::uint32_t(c.z())) << 42) ^ (std::uint64_t(std::uint32_t(c.y())) << 21) ^ std::uint32_t(c.x());
  };
  std::unordered_set<std::uint64_t> seen;
  const auto acc = grid.getConstAccessor();
  int components = 0;
  for (auto it = grid.cbeginValueOn(); it; ++it) {
    if (seen.count(key(it.getCoord()))) continue;
    ++components;
    std::deque<openvdb::Coord> queue{it.getCoord()};
    seen.insert(key(it.getCoord()));
    while (!queue.empty()) {
      const openvdb::Coord c = queue.front();
      queue.pop_front();
      for (int a = 0; a < 3; ++a)
        for (int s : {-1, 1}) {
          openvdb::Coord n = c;
          n[a] += s;
          if (acc.isValueOn(n) && seen.insert(key(n)).second) queue.push_back(n);
        }
    }
  }
  return components;
}

// The exact rule, voxel by voxel: deepest rod wins, ties to the lower index.
struct ExactVoxel {
  bool inside = false;
  int rod = -1;
  double depth = -1, runnerUpDepth = -1e300;
  double value = 0;
};
ExactVoxel exactVoxel(const RodStructure& s, const Vec3& p) {
  ExactVoxel v;
  for (std::size_t r = 0; r < s.rods.size(); ++r) {
    if (!s.rods[r].bounds().contains(p)) continue;  // outside the rod's solid for sure: skip its Newton
    const geometry::RodHit hit = s.rods[r].classify(p);
    if (!hit.inside) continue;
    if (!v.inside || hit.depth > v.depth + voxel::kDepthTieTolerance) {
      v.runnerUpDepth = v.inside ? v.depth : v.runnerUpDepth;
      v = {true, int(r), hit.depth, v.runnerUpDepth, s.rods[r].modulus().value(hit.u)};
    } else {
      v.runnerUpDepth = std::max(v.runnerUpDepth, hit.depth);
    }
  }
  return v;
}

// Every voxel of the grid's box: active exactly where the exact test says inside, with E of the
// winning rod at its closest point. Returns the number of voxels checked.
std::size_t requireMatchesExactTest(const RodStructure& s, const PrinterGrid& g, const voxel::Rasterization& r,
                                    int stride = 1) {
  const auto acc = r.grid->getConstAccessor();
  std::size_t checked = 0, mismatches = 0;
  const geometry::Box3 box = s.bounds();
  openvdb::Coord lo, hi;
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(0, int(std::floor((box.min()[a] - g.origin[a]) / g.voxelSize[a])) - 1);
    hi[a] = std::min(g.dims[a] - 1, int(std::ceil((box.max()[a] - g.origin[a]) / g.voxelSize[a])) + 1);
  }
  for (int k = lo.z(); k <= hi.z(); k += stride)
    for (int j = lo.y(); j <= hi.y(); ++j)
      for (int i = lo.x(); i <= hi.x(); ++i) {
        const openvdb::Coord c(i, j, k);
        const ExactVoxel e = exactVoxel(s, world(g, c));
        float value = 0;
        const bool active = acc.probeValue(c, value);
        ++checked;
        if (active != e.inside) {
          if (++mismatches <= 5) FAIL_CHECK("voxel " << c << ": rasterized " << active << ", exact test " << e.inside);
          continue;
        }
        // A near tie between two rods may go either way within the approximation's bound.
        if (active && e.depth - e.runnerUpDepth > 1e-6) REQUIRE(value == Approx(e.value).epsilon(1e-5));
      }
  REQUIRE(mismatches == 0);
  return checked;
}

}  // namespace

TEST_CASE("The printer grid puts cell (0,0,0) one voxel below the bounding box", "[voxel][grid]") {
  const RodStructure s = design({circularRod(line({1, 2, 3}, {4, 2, 3}), 0.5, CapStyle::Flat)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const geometry::Box3 box = s.bounds();
  REQUIRE(g.voxelSize == kTestVoxel);
  for (int a = 0; a < 3; ++a) {
    // Centres at integer indices: cell (0,0,0) spans [origin - v/2, origin + v/2).
    REQUIRE(g.origin[a] - 0.5 * g.voxelSize[a] == Approx(box.min()[a] - g.voxelSize[a]));
    // The last cell lies wholly beyond the box: an empty layer on every side.
    REQUIRE(g.origin[a] + (g.dims[a] - 1.5) * g.voxelSize[a] >= box.max()[a] - 1e-12);
    REQUIRE(g.origin[a] + (g.dims[a] - 2.5) * g.voxelSize[a] < box.max()[a]);
  }
  const openvdb::math::Transform::Ptr t = g.transform();
  const openvdb::Vec3d w = t->indexToWorld(openvdb::Coord(10, 20, 30));
  REQUIRE(w.x() == Approx(g.origin.x() + 10 * 0.0423));
  REQUIRE(w.y() == Approx(g.origin.y() + 20 * 0.0846));
  REQUIRE(w.z() == Approx(g.origin.z() + 30 * 0.030));
  REQUIRE(t->voxelSize().x() == Approx(0.0423));
  REQUIRE(t->voxelSize().z() == Approx(0.030));
}

TEST_CASE("Bad voxel sizes and empty designs are refused with a clear message", "[voxel][grid][errors]") {
  const RodStructure s = design({circularRod(line({0, 0, 0}, {1, 0, 0}), 0.5, CapStyle::Flat)});
  REQUIRE_THROWS_WITH(voxel::makePrinterGrid(s, {0.04, 0.0, 0.03}), Catch::Contains("voxel size") && Catch::Contains("positive"));
  REQUIRE_THROWS_WITH(voxel::makePrinterGrid(s, {0.04, -1, 0.03}), Catch::Contains("positive"));
  REQUIRE_THROWS_WITH(voxel::makePrinterGrid(s, {std::nan(""), 0.1, 0.03}), Catch::Contains("positive"));
  REQUIRE_THROWS_WITH(voxel::makePrinterGrid(design({}), kTestVoxel), Catch::Contains("test: the design has no rods"));
  REQUIRE_THROWS_WITH(voxel::makePrinterGrid(s, {1e-9, 0.1, 0.1}), Catch::Contains("voxels along an axis"));
}

namespace {

// The grid of `s` with its lattice shifted by `shift` voxels: another placement of the same design.
PrinterGrid shiftedGrid(const RodStructure& s, const openvdb::Vec3d& shift) {
  PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  for (int a = 0; a < 3; ++a) g.origin[a] -= shift[a] * g.voxelSize[a];
  g.dims += openvdb::Coord(1);
  return g;
}

}  // namespace

TEST_CASE("A straight circular rod has the volume of a cylinder, plus two half-balls with round caps", "[voxel][accuracy]") {
  const double r = 8.5 * 0.0423, L = 3.0;  // radius of 8.5 voxels in x
  const Vec3 a(0.3, -0.2, 0.1), dir = Vec3(1, 0.7, 0.4).normalized();
  const double cylinder = kPi * r * r * L, capsule = cylinder + 4.0 / 3.0 * kPi * r * r * r;
  SECTION("oblique: every placement within 1 %") {
    for (const CapStyle caps : {CapStyle::Flat, CapStyle::Round}) {
      const RodStructure s = design({circularRod(line(a, a + L * dir), r, caps)});
      for (const double t : {0.0, 0.3, 0.55, 0.8}) {
        const PrinterGrid g = shiftedGrid(s, {t, 0.7 * t, 0.4 * t});
        const voxel::Rasterization ras = voxel::rasterize(s, g);
        REQUIRE(ras.grid->getName() == "modulus_mpa");
        REQUIRE(occupiedVolume(ras, g) == Approx(caps == CapStyle::Flat ? cylinder : capsule).epsilon(0.01));
      }
    }
  }
  SECTION("along x, y, z: unbiased over placements, each within the lattice noise") {
    // A rod along a grid axis samples its section on one fixed 2D lattice all along its length, so one
    // placement errs by the lattice-point count of an ellipse of 8.5 x 4.25 voxels: up to 3.7 %
    // (measured over 400 random placements); the mean over placements is the exact volume.
    for (const Vec3& d : {Vec3(Vec3::UnitX()), Vec3(Vec3::UnitY()), Vec3(Vec3::UnitZ())}) {
      for (const CapStyle caps : {CapStyle::Flat, CapStyle::Round}) {
        CAPTURE(d.transpose(), caps == CapStyle::Flat);
        const RodStructure s = design({circularRod(line(a, a + L * d), r, caps)});
        const double truth = caps == CapStyle::Flat ? cylinder : capsule;
        double sum = 0.0;
        constexpr int kPlacements = 16;
        for (int n = 0; n < kPlacements; ++n) {
          // A low-discrepancy set of sub-voxel shifts (Kronecker sequence).
          const openvdb::Vec3d shift(std::fmod(n * 0.7548776662, 1.0), std::fmod(n * 0.5698402910, 1.0),
                                     std::fmod(n * 0.4301597090, 1.0));
          const PrinterGrid g = shiftedGrid(s, shift);
          const double v = occupiedVolume(voxel::rasterize(s, g), g);
          REQUIRE(v == Approx(truth).epsilon(0.04));
          sum += v;
        }
        REQUIRE(sum / kPlacements == Approx(truth).epsilon(0.01));
      }
    }
  }
}

TEST_CASE("A NURBS circle swept by a circle has the volume of a torus", "[voxel][accuracy]") {
  const double R = 2.0, r = 0.4;
  const RodStructure s = design({circularRod(arc(R, 2 * kPi, Vec3(0.5, 0.5, 1.0)), r, CapStyle::Flat)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  REQUIRE(occupiedVolume(ras, g) == Approx(2 * kPi * kPi * R * r * r).epsilon(0.01));
  REQUIRE(componentCount(*ras.grid) == 1);
}

TEST_CASE("A helical rod has the volume pi r^2 times its arc length", "[voxel][accuracy]") {
  const double r = 0.36;
  const NurbsCurve c = helix(2.0, 1.6, 2.0);
  const double length = c.arcLength();
  const RodStructure s = design({circularRod(c, r, CapStyle::Flat)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  REQUIRE(occupiedVolume(ras, g) == Approx(kPi * r * r * length).epsilon(0.015));
  REQUIRE(componentCount(*ras.grid) == 1);
}

TEST_CASE("Tight bends (bend radius 1.5 section radii) leave no holes and keep their volume", "[voxel][accuracy]") {
  const double r = 0.4;
  for (const double angle : {0.5 * kPi, kPi, 1.5 * kPi}) {
    CAPTURE(angle);
    const RodStructure s = design({circularRod(arc(1.5 * r, angle), r, CapStyle::Flat)});
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const voxel::Rasterization ras = voxel::rasterize(s, g);
    REQUIRE(componentCount(*ras.grid) == 1);
    // Pappus: a circle swept along an arc of radius R through `angle` encloses pi r^2 R angle.
    REQUIRE(occupiedVolume(ras, g) == Approx(kPi * r * r * 1.5 * r * angle).epsilon(0.01));
  }
}

TEST_CASE("Elliptic and rectangular sections span their width and height along the frame", "[voxel][accuracy]") {
  const double width = 1.1, height = 0.6, L = 2.0;
  const Vec3 oblique = Vec3(1, -0.5, 0.8).normalized();
  for (const Section& section : {Section::ellipse(width, height), Section::rectangle(width, height)}) {
    for (const Vec3& d : {Vec3(Vec3::UnitX()), Vec3(Vec3::UnitY()), Vec3(Vec3::UnitZ()), oblique}) {
      CAPTURE(geometry::toString(section.shape), d.transpose());
      const Vec3 normal = std::abs(d.z()) > 0.9 ? Vec3(1, 0.3, 0) : Vec3(0.2, 0.1, 1);
      const Rod rod("r", line(Vec3::Zero(), L * d), section, normal, std::nullopt, CapStyle::Flat,
                    BSplineField::constant(20, 0, 1));
      const geometry::Frame f = rod.frame().at(rod.centerline(), 0.5);
      const RodStructure s = design({rod});
      const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
      const voxel::Rasterization ras = voxel::rasterize(s, g);
      double lo1 = 1e9, hi1 = -1e9, lo2 = 1e9, hi2 = -1e9;
      for (auto it = ras.grid->cbeginValueOn(); it; ++it) {
        const Vec3 p = world(g, it.getCoord());
        lo1 = std::min(lo1, p.dot(f.d1)), hi1 = std::max(hi1, p.dot(f.d1));
        lo2 = std::min(lo2, p.dot(f.d2)), hi2 = std::max(hi2, p.dot(f.d2));
      }
      // Extent of one voxel along a direction.
      auto voxelExtent = [&](const Vec3& e) {
        return std::abs(e.x()) * g.voxelSize.x() + std::abs(e.y()) * g.voxelSize.y() + std::abs(e.z()) * g.voxelSize.z();
      };
      // The cells' extent (centres' spread plus one voxel) matches the section within one voxel.
      REQUIRE(hi1 - lo1 <= width);
      REQUIRE(hi1 - lo1 + voxelExtent(f.d1) >= width - voxelExtent(f.d1));
      REQUIRE(hi2 - lo2 <= height);
      REQUIRE(hi2 - lo2 + voxelExtent(f.d2) >= height - voxelExtent(f.d2));
      // Flat ends quantize the length to whole layers: up to one voxel's extent of section at each end.
      REQUIRE(occupiedVolume(ras, g) ==
              Approx(section.area() * L).margin(section.area() * voxelExtent(d) + 0.02 * section.area() * L));
    }
  }
}

TEST_CASE("Voxels carry E at their closest centerline point", "[voxel][values]") {
  // Linear E along a straight rod: E at a voxel is E at its projection onto the axis.
  const Vec3 a(0, 0, 0), b(3, 1, 0.5);
  const BSplineField e(1, {0, 0, 1, 1}, {10.0, 130.0});
  const RodStructure s = design({circularRod(line(a, b), 0.4, CapStyle::Flat, e)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  REQUIRE(ras.grid->activeVoxelCount() > 10000);
  const Vec3 axis = b - a;
  for (auto it = ras.grid->cbeginValueOn(); it; ++it) {
    const double u = (world(g, it.getCoord()) - a).dot(axis) / axis.squaredNorm();
    REQUIRE(*it == Approx(10.0 + 120.0 * u).margin(1e-4));
  }

  // Curved rod with a varying E: every voxel against a direct evaluation of the exact test.
  const BSplineField e3(2, {0, 0, 0, 0.5, 1, 1, 1}, {8.0, 150.0, 40.0, 90.0});
  const RodStructure curved = design({circularRod(helix(1.5, 1.2, 1.0), 0.3, CapStyle::Round, e3)});
  const PrinterGrid gc = voxel::makePrinterGrid(curved, kTestVoxel);
  const voxel::Rasterization rc = voxel::rasterize(curved, gc);
  std::size_t n = 0;
  for (auto it = rc.grid->cbeginValueOn(); it; ++it, ++n) {
    if (n % 7 != 0) continue;
    const geometry::RodHit hit = curved.rods[0].classify(world(gc, it.getCoord()));
    REQUIRE(hit.inside);
    REQUIRE(*it == Approx(e3.value(hit.u)).epsilon(1e-5));
  }
}

TEST_CASE("A modulus at its bounds stays within them in every voxel", "[voxel][values]") {
  // An optimizer's output: cubic E(u) whose control values sit at the bounds (8 and 190 MPa), with steep
  // changes between. Interpolating E inside a piece must not step past the values the design asks for,
  // or an optimized design prints with clamped voxels.
  // Runs of four equal controls make E equal to a bound on whole spans, and the transitions between
  // are where an interpolation overshoots.
  const std::vector<double> values{8, 8, 8, 8, 190, 190, 190, 190, 8, 8, 8, 8, 190, 190, 190, 190};
  std::vector<double> knots{0, 0, 0, 0};
  for (int k = 1; k <= 12; ++k) knots.push_back(k / 13.0);
  knots.insert(knots.end(), {1, 1, 1, 1});
  const BSplineField e(3, knots, values);
  const RodStructure s = design({
      Rod("strip", arc(1.2, 0.9 * kPi), Section::rectangle(0.8, 0.3), Vec3(0, 0, 1), std::nullopt, CapStyle::Flat, e),
      Rod("helix", helix(0.9, 1.0, 1.0), Section::circle(0.5), std::nullopt, std::nullopt, CapStyle::Round, e),
  });
  for (const Rod& rod : s.rods) {
    const RodStructure one = design({rod});
    const PrinterGrid g = voxel::makePrinterGrid(one, kTestVoxel);
    const voxel::Rasterization ras = voxel::rasterize(one, g);
    REQUIRE(ras.grid->activeVoxelCount() > 1000);
    float low = 1e30f, high = -1e30f;
    for (auto it = ras.grid->cbeginValueOn(); it; ++it) {
      low = std::min(low, *it);
      high = std::max(high, *it);
    }
    INFO(rod.name());
    CHECK(low >= 8.0f);
    CHECK(high <= 190.0f);
    CHECK(high - low > 150.0f);  // the rod does span the range
  }
}

TEST_CASE("The fast path decides every voxel exactly as Rod::classify", "[voxel][exact]") {
  SECTION("twisted rectangle from a quaternion spline, elliptic helix, round and flat caps") {
    const double s45 = std::sqrt(0.5);
    geometry::QuaternionSpline twist(1, {0, 0, 1, 1}, {{1, 0, 0, 0}, {s45, s45, 0, 0}});  // 90 degrees about x
    const RodStructure s = design({
        Rod("twisted", line({0, 0, 0}, {2.5, 0, 0}), Section::rectangle(0.9, 0.4), std::nullopt, twist,
            CapStyle::Round, BSplineField(1, {0, 0, 1, 1}, {20, 80})),
        Rod("helix", helix(0.9, 1.0, 1.0), Section::ellipse(0.5, 0.3), Vec3(0, 0, 1), std::nullopt, CapStyle::Flat,
            BSplineField(1, {0, 0, 1, 1}, {100, 10})),
        circularRod(arc(0.45, 0.8 * kPi, Vec3(1.0, 1.5, 0.2)), 0.3, CapStyle::Round),
    });
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const voxel::Rasterization ras = voxel::rasterize(s, g);
    REQUIRE(requireMatchesExactTest(s, g, ras) > 100000);
    // The fast path did the work: borderline voxels are a small minority.
    REQUIRE(ras.exactEvaluations * 20 < ras.grid->activeVoxelCount());
  }
  SECTION("a rod that runs over itself (1.25 turns of a circle): its own pieces overlap") {
    const RodStructure s = design({circularRod(arc(1.2, 2.5 * kPi, Vec3(0.2, 0.1, 0.3)), 0.3, CapStyle::Round,
                                               BSplineField(1, {0, 0, 1, 1}, {10, 100}))});
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const voxel::Rasterization ras = voxel::rasterize(s, g);
    REQUIRE(requireMatchesExactTest(s, g, ras) > 50000);
  }
  SECTION("the benchmark lattices, straight and curved, at a smaller scale: 6-rod joints with round caps") {
    for (const double bow : {0.0, 0.15}) {
      examples::LatticeParameters p;
      p.nodes = Eigen::Vector3i(3, 3, 3);
      p.rodDiameter = 0.8;
      p.bow = bow;
      const RodStructure s = examples::cubicLatticeScaledTo({4.0, 4.0, 4.5}, p);
      const PrinterGrid g = voxel::makePrinterGrid(s, {0.05, 0.06, 0.04});
      const voxel::Rasterization ras = voxel::rasterize(s, g);
      REQUIRE(requireMatchesExactTest(s, g, ras, 3) > 100000);
      REQUIRE(ras.voxelsPerRod.size() == 54);
    }
  }
  SECTION("many rods ending at one node: round caps inside the rods around them, coinciding caps, an elliptic and a flat end") {
    // Twelve rods start or end at the node: collinear pairs of equal radius along x, y and z (each cap
    // lies inside the continuing rod), diagonals of other radii, an ellipse whose end plane reaches beyond its
    // round cap, a flat-capped rod. Each rod has its own E, so matching E is matching the owner.
    const Vec3 node(0.013, -0.021, 0.017);
    std::vector<Rod> rods;
    double e = 10.0;
    const auto add = [&](const Vec3& from, const Vec3& to, Section section, CapStyle caps) {
      rods.emplace_back("r", line(from, to), section, std::nullopt, std::nullopt, caps, BSplineField::constant(e, 0, 1));
      e += 10.0;
    };
    for (int axis = 0; axis < 3; ++axis) {
      const Vec3 d = 0.9 * Vec3::Unit(axis);
      add(node - d, node, Section::circle(0.5), CapStyle::Round);  // ends at the node
      add(node, node + d, Section::circle(0.5), CapStyle::Round);  // begins there
    }
    add(node, node + Vec3(0.6, 0.6, 0.6), Section::circle(0.44), CapStyle::Round);
    add(node + Vec3(-0.6, 0.6, -0.5), node, Section::circle(0.36), CapStyle::Round);
    add(node, node + Vec3(0.7, -0.5, 0.2), Section::ellipse(0.56, 0.3), CapStyle::Round);
    add(node + Vec3(-0.3, -0.7, 0.6), node, Section::circle(0.5), CapStyle::Round);  // the same cap as the axis rods
    add(node, node + Vec3(-0.5, -0.4, -0.6), Section::circle(0.3), CapStyle::Flat);
    add(node + Vec3(0.8, 0.1, -0.4), node + Vec3(0.05, 0.0, 0.02), Section::circle(0.4), CapStyle::Round);  // ends near it
    const RodStructure s = design(std::move(rods));
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const voxel::Rasterization ras = voxel::rasterize(s, g);
    REQUIRE(requireMatchesExactTest(s, g, ras) > 100000);
    std::uint64_t won = 0;
    for (std::uint64_t v : ras.voxelsPerRod) won += v;
    REQUIRE(won == ras.grid->activeVoxelCount());
    // Every rod owns part of the joint or of its own length, and two threads agree to the bit.
    for (std::uint64_t v : ras.voxelsPerRod) REQUIRE(v > 0);
    const voxel::Rasterization two = voxel::rasterize(s, g, {2});
    REQUIRE(two.voxelsPerRod == ras.voxelsPerRod);
    const auto acc = two.grid->getConstAccessor();
    for (auto it = ras.grid->cbeginValueOn(); it; ++it) REQUIRE(acc.getValue(it.getCoord()) == *it);
  }
  SECTION("the bundled buckling spring (every 5th layer)") {
    const RodStructure s = examples::bucklingSpring();
    const PrinterGrid g = voxel::makePrinterGrid(s, {0.2, 0.2, 0.2});
    const voxel::Rasterization ras = voxel::rasterize(s, g);
    REQUIRE(requireMatchesExactTest(s, g, ras, 5) > 100000);
  }
}

TEST_CASE("Overlapping rods: the deepest wins, ties go to the lower rod index", "[voxel][overlap]") {
  SECTION("a cross joint follows the exact rule") {
    const RodStructure s = design({circularRod(line({-1, 0, 0}, {1, 0, 0}), 0.35, CapStyle::Round, BSplineField::constant(10, 0, 1)),
                                   circularRod(line({0.1, -1, 0.05}, {0.1, 1, 0.05}), 0.3, CapStyle::Round, BSplineField::constant(90, 0, 1))});
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const voxel::Rasterization ras = voxel::rasterize(s, g);
    requireMatchesExactTest(s, g, ras);
    REQUIRE(ras.voxelsPerRod[0] + ras.voxelsPerRod[1] == ras.grid->activeVoxelCount());
    // Both rods win some of the joint.
    const auto acc = ras.grid->getConstAccessor();
    const openvdb::Coord onAxis0 = g.transform()->worldToIndexCellCentered(openvdb::Vec3d(0.1, 0, 0));
    const openvdb::Coord onAxis1 = g.transform()->worldToIndexCellCentered(openvdb::Vec3d(0.1, 0.0, 0.05 + 0.2));
    REQUIRE(acc.getValue(onAxis0) == 10.0f);  // 0.05 off rod 1's axis, 0 off rod 0's: relatively deeper in 0
    REQUIRE(acc.getValue(onAxis1) == 90.0f);
  }
  SECTION("identical rods: the first one takes every voxel") {
    const Rod a = circularRod(helix(1.0, 0.8, 0.5), 0.3, CapStyle::Round, BSplineField::constant(33, 0, 1));
    const Rod b = circularRod(helix(1.0, 0.8, 0.5), 0.3, CapStyle::Round, BSplineField::constant(77, 0, 1));
    const RodStructure s = design({a, b});
    const voxel::Rasterization ras = voxel::rasterize(s, voxel::makePrinterGrid(s, kTestVoxel));
    REQUIRE(ras.voxelsPerRod[1] == 0);
    REQUIRE(ras.voxelsPerRod[0] == ras.grid->activeVoxelCount());
    for (auto it = ras.grid->cbeginValueOn(); it; ++it) REQUIRE(*it == 33.0f);
  }
}

namespace {

void requireIdentical(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b) {
  REQUIRE(a.activeVoxelCount() == b.activeVoxelCount());
  const auto acc = b.getConstAccessor();
  for (auto it = a.cbeginValueOn(); it; ++it) {
    float v = 0;
    REQUIRE(acc.probeValue(it.getCoord(), v));
    REQUIRE(v == *it);  // bit-identical, not approximately equal
  }
}

}  // namespace

TEST_CASE("The grid is identical for 1 and 2 threads and for any band of layers", "[voxel][determinism]") {
  const RodStructure s = examples::bucklingSpring();
  const PrinterGrid g = voxel::makePrinterGrid(s, {0.08, 0.1, 0.06});
  const voxel::Rasterization one = voxel::rasterize(s, g, {1});
  const voxel::Rasterization two = voxel::rasterize(s, g, {2});
  requireIdentical(*one.grid, *two.grid);
  REQUIRE(one.voxelsPerRod == two.voxelsPerRod);
  REQUIRE(one.exactEvaluations == two.exactEvaluations);

  // Bands of odd sizes, not aligned with leaves: their union is the whole grid, voxel for voxel.
  const voxel::Rasterizer rasterizer(s, g, {2});
  std::uint64_t total = 0;
  std::vector<std::uint64_t> perRod(s.rods.size(), 0);
  for (int z0 = -3; z0 < g.dims.z(); z0 += 37) {
    const voxel::Rasterization band = rasterizer.rasterizeLayers(z0, z0 + 37);
    total += band.grid->activeVoxelCount();
    const auto acc = one.grid->getConstAccessor();
    for (auto it = band.grid->cbeginValueOn(); it; ++it) {
      REQUIRE(it.getCoord().z() >= z0);
      REQUIRE(it.getCoord().z() < z0 + 37);
      float v = 0;
      REQUIRE(acc.probeValue(it.getCoord(), v));
      REQUIRE(v == *it);
    }
    for (std::size_t r = 0; r < perRod.size(); ++r) perRod[r] += band.voxelsPerRod[r];
  }
  REQUIRE(total == one.grid->activeVoxelCount());
  REQUIRE(perRod == one.voxelsPerRod);
  REQUIRE(rasterizer.rasterizeLayers(g.dims.z(), g.dims.z() + 10).grid->activeVoxelCount() == 0);
}

TEST_CASE("Memory follows the active voxels, not the envelope", "[voxel][sparse]") {
  // Two short rods 85 mm apart: a 2000 x 1000 x 3000 voxel envelope (6 gigavoxels) holding ~4,700 voxels.
  const RodStructure s = design({circularRod(line({0, 0, 0}, {0.5, 0, 0}), 0.3, CapStyle::Round),
                                 circularRod(line({84, 84, 89}, {84, 84, 89.5}), 0.3, CapStyle::Round)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  REQUIRE(g.voxelCount() > 5'000'000'000ull);
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  const auto active = ras.grid->activeVoxelCount();
  const double capsule = kPi * 0.09 * 0.5 + 4.0 / 3.0 * kPi * 0.027;
  REQUIRE(double(active) * g.voxelVolume() == Approx(2 * capsule).epsilon(0.04));
  REQUIRE(ras.grid->tree().leafCount() * 512 < 4 * active);
  REQUIRE(ras.grid->memUsage() < 100 * active);
}

TEST_CASE("The memory estimate made before rasterizing bounds the grid OpenVDB builds", "[voxel][sparse][memory]") {
  // OpenVDB's own count of the tree's bytes is the independent truth; the estimate must not fall below
  // it (a refusal would come too late) nor exceed it by so much that fitting designs are refused.
  const Vec3 a(0.1, 0.2, 0.3), dir = Vec3(0.8, 0.5, 0.3).normalized();
  const std::vector<std::pair<std::string, Rod>> rods = {
      {"thick round", circularRod(line(a, a + 4.0 * dir), 1.2, CapStyle::Round)},
      {"thin round", circularRod(line(a, a + 6.0 * dir), 0.1, CapStyle::Flat)},
      {"flat ellipse", Rod("e", line(a, a + 5.0 * dir), Section::ellipse(3.0, 0.05), Vec3(0, 0, 1), std::nullopt,
                           CapStyle::Flat, BSplineField::constant(50, 0, 1))},
      {"rectangle", Rod("r", line(a, a + 5.0 * dir), Section::rectangle(1.5, 0.8), Vec3(0, 0, 1), std::nullopt,
                        CapStyle::Round, BSplineField::constant(50, 0, 1))},
  };
  for (const auto& [name, rod] : rods) {
    CAPTURE(name);
    const RodStructure s = design({rod});
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const double built = double(voxel::rasterize(s, g).grid->memUsage());
    const double estimate = double(voxel::estimateRasterizationBytes(s, g));
    CAPTURE(built, estimate);
    REQUIRE(estimate >= built);
    REQUIRE(estimate <= 3.0 * built);
  }
  SECTION("a part far beyond any memory is estimated without overflow") {
    const RodStructure s = design({circularRod(line({0, 0, 0}, {300, 0, 0}), 75.0, CapStyle::Round)});
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const double voxels = kPi * 75.0 * 75.0 * 300.0 / g.voxelVolume();
    REQUIRE(double(voxel::estimateRasterizationBytes(s, g)) >= 4.0 * voxels);
  }
}

TEST_CASE("Grid statistics agree with a direct count", "[voxel][statistics]") {
  const BSplineField e(1, {0, 0, 1, 1}, {12.0, 60.0});
  const RodStructure s = design({circularRod(line({0, 0, 0}, {2, 0, 0}), 0.4, CapStyle::Flat, e),
                                 circularRod(line({0, 1, 0}, {0, 1, 2}), 0.3, CapStyle::Round)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  const voxel::GridStatistics st = voxel::computeStatistics(*ras.grid, g, ras.voxelsPerRod);
  std::uint64_t n = 0;
  double sum = 0, lo = 1e9, hi = -1e9;
  openvdb::CoordBBox box;
  for (auto it = ras.grid->cbeginValueOn(); it; ++it, ++n) {
    sum += *it, lo = std::min<double>(lo, *it), hi = std::max<double>(hi, *it);
    box.expand(it.getCoord());
  }
  REQUIRE(st.activeVoxels == n);
  REQUIRE(st.occupiedVolumeMm3 == Approx(n * 0.0423 * 0.0846 * 0.030));
  REQUIRE(st.modulusMin == Approx(lo));
  REQUIRE(st.modulusMax == Approx(hi));
  REQUIRE(st.modulusMean == Approx(sum / n));
  // E rises 24 MPa/mm along x; the outermost voxel centres lie within one voxel of the rod's ends.
  REQUIRE(lo == Approx(12.0).margin(24 * 0.0423));
  REQUIRE(hi == Approx(60.0).margin(24 * 0.0423));
  REQUIRE(st.boundsVoxels == box);
  REQUIRE(st.boundsMinMm.x() == Approx(-0.3).margin(0.0423));  // the second rod's radius; the first ends flat at 0
  REQUIRE(st.boundsMaxMm.z() == Approx(2.3).margin(0.03));
  REQUIRE(st.voxelsPerRod.size() == 2);
  REQUIRE(st.voxelsPerRod[0] + st.voxelsPerRod[1] == n);
  // An axis-aligned rod: within the lattice noise of its section (see the straight-rod test).
  REQUIRE(double(st.voxelsPerRod[0]) * g.voxelVolume() == Approx(kPi * 0.16 * 2).epsilon(0.04));

  const voxel::GridStatistics empty = voxel::computeStatistics(*openvdb::FloatGrid::create(), g);
  REQUIRE(empty.activeVoxels == 0);
  REQUIRE(empty.boundsVoxels.empty());
}

TEST_CASE(".vdb files round-trip and are written atomically", "[voxel][io]") {
  const RodStructure s = design({circularRod(arc(1.0, kPi), 0.3, CapStyle::Round)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "rodfab-test-voxel";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "bend.vdb").string();
  voxel::writeGridFile(path, *ras.grid);
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    REQUIRE(entry.path().filename() == "bend.vdb");  // no temporary left behind
  const openvdb::FloatGrid::Ptr back = voxel::readFloatGrid(path, voxel::kModulusGridName);
  requireIdentical(*ras.grid, *back);
  REQUIRE(back->transform() == ras.grid->transform());

  REQUIRE_THROWS_WITH(voxel::readFloatGrid(path, "density"), Catch::Contains("bend.vdb") && Catch::Contains("density"));
  REQUIRE_THROWS_WITH(voxel::readFloatGrid((dir / "missing.vdb").string(), "modulus_mpa"), Catch::Contains("missing.vdb"));
  REQUIRE_THROWS_WITH(voxel::writeGridFile((dir / "no-such-dir" / "x.vdb").string(), *ras.grid),
                      Catch::Contains("x.vdb: cannot write"));
  std::filesystem::remove_all(dir);
}

// ---- Kinks, folds, extreme weights and hostile sizes ----

namespace {

// An independent reference for the rod's solid (geometry/rod.hpp): the union over the smooth pieces,
// given here by the test that built the curve, of the sections swept along dense samples (no sample
// farther than 4 um from the next, found by bisecting the parameter, so extreme weights are followed)
// plus round caps. A section through p is found where (p - r(u)) . t(u) changes sign between two
// samples (and the tangent does not reverse: a cusp); p's frame coordinates there are interpolated linearly. Ends are sampled a hair inside the
// piece, so no evaluation happens at a kink.
struct RefSample {
  double u;
  Vec3 r, t, d1, d2;
};

RefSample refSample(const Rod& rod, double u) {
  Vec3 d[3];
  rod.centerline().derivatives(u, 2, d);
  const Vec3 t = d[1].normalized();
  const geometry::Frame f = rod.frame().at(u, d[0], t);
  return {u, d[0], t, f.d1, f.d2};
}

std::vector<RefSample> refSamples(const Rod& rod, double a, double b) {
  const double inset = 1e-11 * (b - a);
  a += inset;
  b -= inset;
  std::vector<RefSample> out{refSample(rod, a)};
  auto split = [&](auto&& self, const RefSample& x, const RefSample& y, int depth) -> void {
    if (depth < 40 && (y.r - x.r).norm() > 0.004) {
      const RefSample m = refSample(rod, 0.5 * (x.u + y.u));
      self(self, x, m, depth + 1);
      self(self, m, y, depth + 1);
      return;
    }
    out.push_back(y);
  };
  constexpr int kStart = 64;
  for (int k = 0; k < kStart; ++k) split(split, out.back(), refSample(rod, a + (b - a) * (k + 1) / kStart), 0);
  return out;
}

struct RefHit {
  double depth = -1e300, runnerUp = -1e300, u = 0;
  double uncertainty = 0;  // of E at u: E's change between the two samples the section lies between
  bool nearEndPlane = false;  // on a flat end's plane within the section: either answer is right
};

struct Reference {
  const Rod* rod;
  std::vector<std::vector<RefSample>> pieces;

  Reference(const Rod& r, const std::vector<double>& breaks) : rod(&r) {
    for (std::size_t k = 0; k + 1 < breaks.size(); ++k) pieces.push_back(refSamples(r, breaks[k], breaks[k + 1]));
  }

  RefHit at(const Vec3& p) const {
    RefHit h;
    auto take = [&](double depth, double u, double uncertainty = 0) {
      if (depth > h.depth) {
        h.runnerUp = h.depth;
        h.depth = depth;
        h.u = u;
        h.uncertainty = uncertainty;
      } else {
        h.runnerUp = std::max(h.runnerUp, depth);
      }
    };
    const geometry::Section& sec = rod->section();
    const double reach = sec.boundingRadius() + 0.01;
    for (const auto& S : pieces) {
      for (const bool atEnd : {false, true}) {
        const RefSample& e = atEnd ? S.back() : S.front();
        const Vec3 w = p - e.r;
        const double beyond = (atEnd ? 1.0 : -1.0) * w.dot(e.t);
        if (rod->caps() == CapStyle::Round && beyond > 0) take(1.0 - w.norm() / sec.capRadius(), e.u);
        if (std::abs(beyond) < 1e-3 && sec.normalizedRadius(w.dot(e.d1), w.dot(e.d2)) < 1.01) h.nearEndPlane = true;
      }
      for (std::size_t i = 0; i + 1 < S.size(); ++i) {
        const Vec3 wa = p - S[i].r, wb = p - S[i + 1].r;
        if (wa.norm() > reach + 0.01 && wb.norm() > reach + 0.01) continue;
        const double a = wa.dot(S[i].t), b = wb.dot(S[i + 1].t);
        // A sign change where the tangent reverses (a cusp between the samples) is no plane crossing.
        if ((a >= 0) == (b >= 0) || S[i].t.dot(S[i + 1].t) < 0.5) continue;
        const double l = a / (a - b);
        const double x1 = (1 - l) * wa.dot(S[i].d1) + l * wb.dot(S[i + 1].d1);
        const double x2 = (1 - l) * wa.dot(S[i].d2) + l * wb.dot(S[i + 1].d2);
        take(1.0 - sec.normalizedRadius(x1, x2), (1 - l) * S[i].u + l * S[i + 1].u,
             std::abs(rod->modulus().value(S[i + 1].u) - rod->modulus().value(S[i].u)));
      }
    }
    return h;
  }
};

// Every voxel around the rod: active exactly where the reference says inside (voxels within 2e-3 of
// the boundary in depth, or on a flat end plane, may go either way), E as at the reference's deepest
// section, and nothing active, or inside the reference, outside the part bounds the job writer checks.
void requireMatchesReference(const Rod& rod, const std::vector<double>& breaks, const openvdb::Vec3d& voxelSize) {
  const RodStructure s = design({rod});
  const PrinterGrid g = voxel::makePrinterGrid(s, voxelSize);
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  const Reference ref(rod, breaks);
  const geometry::Box3 b = s.bounds();
  const openvdb::CoordBBox part = g.voxelsWithin({b.min().x(), b.min().y(), b.min().z()}, {b.max().x(), b.max().y(), b.max().z()});
  const auto acc = ras.grid->getConstAccessor();
  std::size_t checked = 0, inside = 0, mismatches = 0;
  for (int k = 0; k < g.dims.z(); ++k)
    for (int j = 0; j < g.dims.y(); ++j)
      for (int i = 0; i < g.dims.x(); ++i) {
        const openvdb::Coord c(i, j, k);
        float value = 0;
        const bool active = acc.probeValue(c, value);
        if (active) REQUIRE(part.isInside(c));
        const RefHit h = ref.at(world(g, c));
        if (std::abs(h.depth) < 2e-3 || h.nearEndPlane) continue;
        ++checked;
        if (h.depth > 0) {
          ++inside;
          REQUIRE(part.isInside(c));
        }
        if (active != (h.depth > 0)) {
          if (++mismatches <= 5) FAIL_CHECK("voxel " << c << " at " << world(g, c).transpose() << ": rasterized " << active << ", reference depth " << h.depth);
          continue;
        }
        if (active && h.depth - h.runnerUp > 1e-3 &&
            !(std::abs(value - rod.modulus().value(h.u)) <= 2e-3 * std::abs(value) + h.uncertainty)) {
          const geometry::RodHit e = rod.classify(world(g, c));
          FAIL("voxel " << c << " at " << world(g, c).transpose() << ": E " << value << ", reference " << rod.modulus().value(h.u)
                        << " at u " << h.u << " depth " << h.depth << " (runner-up " << h.runnerUp << "), classify u " << e.u << " depth " << e.depth);
        }
      }
  REQUIRE(mismatches == 0);
  REQUIRE(inside > 1000);
  REQUIRE(checked > inside);
  // And the rasterizer agrees with Rod::classify everywhere (not only away from the boundary).
  requireMatchesExactTest(s, g, ras);
}

NurbsCurve polyline(const std::vector<Vec3>& pts) {
  std::vector<double> knots{0};
  for (std::size_t i = 0; i < pts.size(); ++i) knots.push_back(double(i) / double(pts.size() - 1));
  knots.push_back(1);
  return NurbsCurve(1, knots, pts);
}

Rod makeRod(NurbsCurve c, Section sec, CapStyle caps, std::optional<Vec3> normal = std::nullopt) {
  return Rod("rod", std::move(c), sec, normal, std::nullopt, caps, BSplineField(1, {0, 0, 1, 1}, {10, 100}));
}

// The README's example centerline (a cubic S bend), with optional weights.
NurbsCurve readmeCurve(std::vector<double> weights = {}) {
  return NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1, 1}, {{0, 0, 0}, {1, 0, 0}, {2, 1, 0}, {3, 1, 0}}, std::move(weights));
}

}  // namespace

TEST_CASE("A kinked centerline is the union of its smooth pieces, voxel for voxel as a brute-force reference", "[voxel][kink]") {
  const openvdb::Vec3d voxel(0.05, 0.07, 0.04);
  SECTION("degree-1 polyline bent by 45 degrees in x-y, round caps: a ball joint") {
    const Rod rod = makeRod(polyline({{0, 0, 0}, {2, 0, 0}, {3.2, 1.2, 0}}), Section::circle(1.0), CapStyle::Round);
    REQUIRE(rod.smoothPieces().size() == 2);
    requireMatchesReference(rod, {0, 0.5, 1}, voxel);
  }
  SECTION("bent by 90 degrees in x-z, flat caps: the outer corner is notched") {
    const Rod rod = makeRod(polyline({{0, 0, 0}, {2, 0, 0}, {2, 0, 2}}), Section::circle(0.8), CapStyle::Flat);
    requireMatchesReference(rod, {0, 0.5, 1}, voxel);
    // The corner's outer wedge: beyond both pieces' end planes.
    REQUIRE_FALSE(rod.classify(Vec3(2.3, 0, -0.2)).inside);
  }
  SECTION("a rectangle bent by 135 degrees in x-y and twice more out of plane") {
    const Rod rod = makeRod(polyline({{0, 0, 0}, {2, 0, 0}, {0.6, 1.4, 0}, {0.6, 1.4, 1.5}, {1.6, 2.0, 2.0}}),
                            Section::rectangle(0.7, 0.4), CapStyle::Round, Vec3(0, 0, 1));
    REQUIRE(rod.smoothPieces().size() == 4);
    requireMatchesReference(rod, {0, 0.25, 0.5, 0.75, 1}, voxel);
  }
  SECTION("a double interior knot on a quadratic: an elliptic section with a corner") {
    const Rod rod("rod", NurbsCurve(2, {0, 0, 0, 0.5, 0.5, 1, 1, 1}, {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 1, 0.5}, {2.2, 2, 1}}),
                  Section::ellipse(0.9, 0.5), Vec3(0, 0, 1), std::nullopt, CapStyle::Flat, BSplineField(1, {0, 0, 1, 1}, {10, 100}));
    REQUIRE(rod.smoothPieces().size() == 2);
    requireMatchesReference(rod, {0, 0.5, 1}, voxel);
  }
  SECTION("a polyline folding back on itself (a 180 degree cusp)") {
    const Rod rod = makeRod(polyline({{0, 0, 0}, {2, 0, 0}, {0.8, 0, 0.3}}), Section::circle(0.6), CapStyle::Round);
    requireMatchesReference(rod, {0, 0.5, 1}, voxel);
  }
  SECTION("a double knot with the control points in line is no kink") {
    const Rod rod("rod", NurbsCurve(2, {0, 0, 0, 0.5, 0.5, 1, 1, 1}, {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {3, 1, 0}}),
                  Section::circle(0.5), std::nullopt, std::nullopt, CapStyle::Round, BSplineField::constant(5, 0, 1));
    REQUIRE(rod.smoothPieces().size() == 1);
  }
}

TEST_CASE("Rows of every length and offset: rods along x, y and z across block edges, overlapping at a kink", "[voxel][exact][kink]") {
  // The swept loop fills four neighbours along x at once and the blocks are 64 voxels long in x: rows
  // of 1 to 3 voxels (thin rods across x), rows starting at every offset, rows cut by a block edge and
  // slots already filled by another rod (joints, a kink's overlapping pieces) all take other paths.
  const openvdb::Vec3d voxel(0.05, 0.07, 0.04);
  const BSplineField rising(1, {0, 0, 1, 1}, {12, 150});
  const RodStructure s = design({
      Rod("thin-along-x", line({0.1, 0.62, 0.5}, {6.3, 0.66, 0.52}), Section::circle(0.12), std::nullopt, std::nullopt,
          CapStyle::Round, rising),
      Rod("flat-along-y", line({3.17, -0.2, 0.45}, {3.2, 1.6, 0.5}), Section::rectangle(0.5, 0.26), Vec3(0, 0, 1), std::nullopt,
          CapStyle::Flat, BSplineField::constant(70, 0, 1)),
      makeRod(polyline({{0.4, 0.6, 0.1}, {3.25, 0.7, 0.5}, {3.3, 0.75, 1.9}}), Section::rectangle(0.3, 0.22), CapStyle::Round,
              Vec3(0, 1, 0)),
      Rod("thin-along-z", line({3.2, 0.64, -0.4}, {3.21, 0.64, 1.4}), Section::circle(0.07), std::nullopt, std::nullopt,
          CapStyle::Round, BSplineField::constant(180, 0, 1)),
  });
  const PrinterGrid g = voxel::makePrinterGrid(s, voxel);
  REQUIRE(g.dims.x() > 128);  // the x rod crosses two block edges
  for (const int threads : {1, 2}) {
    const voxel::Rasterization ras = voxel::rasterize(s, g, {threads});
    REQUIRE(requireMatchesExactTest(s, g, ras) > 100000);
    std::uint64_t won = 0;
    for (const std::uint64_t n : ras.voxelsPerRod) {
      REQUIRE(n > 0);
      won += n;
    }
    REQUIRE(won == ras.grid->activeVoxelCount());
    // Inactive voxels of the leaves hold the background, as OpenVDB writes them.
    for (auto leaf = ras.grid->tree().cbeginLeaf(); leaf; ++leaf)
      for (auto v = leaf->cbeginValueOff(); v; ++v) REQUIRE(*v == 0.0f);
  }
}

TEST_CASE("Tight bends, extreme weights and rods thicker than their bend agree with the reference", "[voxel][kink]") {
  const openvdb::Vec3d voxel(0.06, 0.08, 0.05);
  SECTION("the README's S bend with diameter 4: the sections fold over inside the bends") {
    requireMatchesReference(makeRod(readmeCurve(), Section::circle(4.0), CapStyle::Round), {0, 1}, {0.1, 0.12, 0.09});
  }
  SECTION("weights [1, 1e3, 1e3, 1]: the curve hugs its control polygon, the parameter races at the ends") {
    const Rod rod = makeRod(readmeCurve({1, 1e3, 1e3, 1}), Section::circle(1.5), CapStyle::Round);
    REQUIRE(rod.smoothPieces().size() == 1);
    requireMatchesReference(rod, {0, 1}, voxel);
  }
  SECTION("weights [1, 1e6, 1e6, 1]: nearly a polyline, corners sharper than the voxels") {
    requireMatchesReference(makeRod(readmeCurve({1, 1e6, 1e6, 1}), Section::circle(1.0), CapStyle::Flat), {0, 1}, voxel);
  }
  SECTION("a cubic with a cusp inside its span") {
    requireMatchesReference(makeRod(NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1, 1}, {{0, 0, 0}, {2, 2, 0}, {0, 2, 0}, {2, 0, 0}}),
                                    Section::circle(0.8), CapStyle::Round),
                            {0, 1}, voxel);
  }
}

TEST_CASE("Hostile sizes stay bounded: pieces within the estimate, work within seconds", "[voxel][bounded]") {
  struct Case {
    const char* name;
    Rod rod;
  };
  const Case cases[] = {
      {"README bend, diameter 4", makeRod(readmeCurve(), Section::circle(4.0), CapStyle::Round)},
      {"weights 1e3", makeRod(readmeCurve({1, 1e3, 1e3, 1}), Section::circle(1.5), CapStyle::Round)},
      {"5 x 0.01 mm ellipse", makeRod(readmeCurve(), Section::ellipse(5, 0.01), CapStyle::Round, Vec3(0, 0, 1))},
      {"1e8 mm from the origin", makeRod(NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1, 1}, {{1e8, 1e8, 0}, {1e8 + 1, 1e8, 0}, {1e8 + 2, 1e8 + 1, 0}, {1e8 + 3, 1e8 + 1, 0}}),
                                         Section::circle(1.5), CapStyle::Round)},
      {"E jumping 8 -> 120 MPa", Rod("jump", readmeCurve(), Section::circle(1.5), std::nullopt, std::nullopt, CapStyle::Round,
                                      BSplineField(1, {0, 0, 0.5, 0.5, 1, 1}, {8, 8, 120, 120}))},
  };
  for (const Case& c : cases) {
    INFO(c.name);
    const RodStructure s = design({c.rod});
    const PrinterGrid g = voxel::makePrinterGrid(s, {0.06, 0.08, 0.05});
    const voxel::RasterEstimate estimate = voxel::estimateRaster(s, g);
    const voxel::Rasterizer rasterizer(s, g);
    REQUIRE(rasterizer.pieceCount() <= estimate.maxPieces);
    REQUIRE(estimate.pieceBytes < 5e6);
    const voxel::Rasterization ras = rasterizer.rasterize();
    REQUIRE(ras.grid->activeVoxelCount() > 0);
    REQUIRE(double(ras.grid->activeVoxelCount()) <= 1.3 * estimate.activeVoxels);  // folds hold more than Pappus says
  }
  SECTION("far from the origin the rod is the same as at the origin, voxel for voxel up to the lattice's shift") {
    const RodStructure near = design({makeRod(readmeCurve(), Section::circle(1.5), CapStyle::Round)});
    const RodStructure far = design({cases[3].rod});
    const auto n = voxel::rasterize(near, voxel::makePrinterGrid(near, kTestVoxel)).grid->activeVoxelCount();
    const auto f = voxel::rasterize(far, voxel::makePrinterGrid(far, kTestVoxel)).grid->activeVoxelCount();
    REQUIRE(double(f) == Approx(double(n)).epsilon(0.002));
  }
  SECTION("a jump of E: values on each side as the field says") {
    const RodStructure s = design({cases[4].rod});
    const PrinterGrid g = voxel::makePrinterGrid(s, {0.05, 0.05, 0.05});
    requireMatchesExactTest(s, g, voxel::rasterize(s, g));
  }
}

TEST_CASE("Interruption: the hook is polled often and stops construction and rasterization", "[voxel][interrupt]") {
  const RodStructure s = design({makeRod(readmeCurve(), Section::circle(4.0), CapStyle::Round)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  using Clock = std::chrono::steady_clock;
  std::atomic<long> calls{0};
  std::mutex mutex;
  Clock::time_point last = Clock::now();
  double longestGap = 0;
  auto poll = [&](long stopAfter) {
    return [&, stopAfter] {
      std::lock_guard<std::mutex> lock(mutex);
      const Clock::time_point now = Clock::now();
      longestGap = std::max(longestGap, std::chrono::duration<double>(now - last).count());
      last = now;
      return ++calls > stopAfter;
    };
  };
  SECTION("never interrupted: the same grid, polled throughout") {
    const voxel::Rasterization plain = voxel::rasterize(s, g, {1});
    last = Clock::now();
    const voxel::Rasterization polled = voxel::rasterize(s, g, {1, poll(std::numeric_limits<long>::max())});
    requireIdentical(*plain.grid, *polled.grid);
    REQUIRE(calls > 100);
    WARN("longest time between polls: " << longestGap * 1e3 << " ms over " << calls << " polls");
    REQUIRE(longestGap < 0.5);  // ~10 ms on an idle machine; generous for a loaded one
  }
  SECTION("interrupted while cutting the rods into pieces") {
    REQUIRE_THROWS_AS(voxel::Rasterizer(s, g, {1, poll(0)}), voxel::Interrupted);
  }
  SECTION("interrupted while rasterizing") {
    const voxel::Rasterizer rasterizer(s, g, {2, poll(std::numeric_limits<long>::max())});
    calls = 0;
    const voxel::Rasterizer stopping(s, g, {2, [&] { return ++calls > 2000; }});
    REQUIRE_THROWS_AS(stopping.rasterize(), voxel::Interrupted);
  }
  SECTION("interrupted at any poll, inside the AVX2-cloned swept and cap loops too") {
    // GCC 12 treats a call to a target_clones function as unable to throw: an Interrupted leaving the
    // swept loop ended the process (std::terminate, 1 SIGINT in 10 during `rodfab slice`). The round
    // caps' loop is cloned too, and its voxels on the end planes go to the exact test, which polls.
    long polls = 0;
    bool armed = false;
    const voxel::Rasterizer counting(s, g, {1, [&] { return armed && ++polls < 0; }});
    armed = true;
    counting.rasterize();
    REQUIRE(polls > 200);
    for (long stop = 0; stop < polls; stop += std::max(1L, polls / 300)) {
      long n = 0;
      bool live = false;
      const voxel::Rasterizer stopping(s, g, {1, [&] { return live && ++n > stop; }});
      live = true;
      CHECK_THROWS_AS(stopping.rasterize(), voxel::Interrupted);
    }
  }
}

TEST_CASE("Estimates before allocating: voxels, leaves and pieces of straight and curved rods", "[voxel][estimate]") {
  const RodStructure s = design({circularRod(line({0, 0, 0}, {6, 1, 2}), 0.5, CapStyle::Round),
                                 circularRod(helix(2.0, 1.5, 2.0), 0.4, CapStyle::Flat)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const voxel::RasterEstimate e = voxel::estimateRaster(s, g, 64);
  const voxel::Rasterizer rasterizer(s, g);
  const voxel::Rasterization ras = rasterizer.rasterize();
  REQUIRE(double(ras.grid->activeVoxelCount()) == Approx(e.activeVoxels).epsilon(0.03));
  const double leaves = double(ras.grid->tree().leafCount());
  REQUIRE(e.leaves >= leaves);
  REQUIRE(e.leaves <= 3.0 * leaves);
  REQUIRE(e.gridBytes >= double(ras.grid->memUsage()) * 0.9);
  REQUIRE(e.gridBytes <= double(ras.grid->memUsage()) * 4);
  REQUIRE(rasterizer.pieceCount() <= e.maxPieces);
  REQUIRE(e.bandBytes > 0);
  REQUIRE(e.bandBytes <= e.gridBytes);
  REQUIRE(e.peakBytes(2) == e.pieceBytes + 2 * e.bandBytes);
  REQUIRE(e.peakBytes(0) == e.pieceBytes + e.gridBytes);
}

TEST_CASE("Rods below the printer's resolution are listed for a warning", "[voxel][thin]") {
  const RodStructure s = design({circularRod(line({0, 0, 0}, {3, 0, 0}), 0.5, CapStyle::Round),
                                 circularRod(line({0, 2, 0}, {3, 2, 0}), 0.01, CapStyle::Round),
                                 circularRod(line({0.5, 0, 0}, {2.5, 0, 0}), 0.2, CapStyle::Round)});  // inside rod 0
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const std::vector<voxel::ThinRod> before = voxel::findThinRods(s, g);
  REQUIRE(before.size() == 1);
  REQUIRE(before[0].rod == 1);
  REQUIRE(before[0].thinnestMm == Approx(0.02));
  REQUIRE_THAT(before[0].reason, Catch::Contains("rod 1 ('rod')") && Catch::Contains("0.02 mm thin") && Catch::Contains("0.0846"));
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  const std::vector<voxel::ThinRod> after = voxel::findThinRods(s, g, ras.voxelsPerRod);
  REQUIRE(after.size() == 2);
  REQUIRE(after[0].rod == 1);
  REQUIRE(after[0].voxels == ras.voxelsPerRod[1]);  // a row of voxels, or none, by where the lattice falls
  REQUIRE(after[1].rod == 2);  // hidden inside rod 0: it wins no voxel
  REQUIRE_THAT(after[1].reason, Catch::Contains("holds 0 voxels"));
  REQUIRE(after[1].expectedVoxels == Approx(kPi * 0.04 * 2 / g.voxelVolume() + 4.0 / 3.0 * kPi * 0.008 / g.voxelVolume()));
  REQUIRE_THROWS_WITH(voxel::findThinRods(s, g, {1, 2}), Catch::Contains("one voxel count per rod (3), got 2"));
}
