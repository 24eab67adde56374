// voxel/: rasterization against analytic volumes, the exact per-voxel test, and itself (threads, bands).
#include "voxel/voxel.hpp"
#include "voxel/raster_clips.hpp"
#include "voxel/rod_pieces.hpp"

#include "examples/example_designs.hpp"
#include "geometry/geometry.hpp"
#include "tests/voxel_fixture.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <numbers>
#include <unordered_set>
#include <utility>
#include <vector>

using namespace rodfab;
using namespace rodfab::test;  // with the fixture's geometry and voxel names

namespace {

// Circular arc of radius R about c in the xy-plane from angle `start` to start + `angle` (angle <= 2 pi),
// exact rational quadratic with one span per quarter turn (at most).
NurbsCurve arc(double R, double angle, const Vec3& c = Vec3::Zero(), double start = 0.0) {
  const int spans = std::max(1, static_cast<int>(std::ceil(angle / (0.5 * kPi) - 1e-9)));
  const double step = angle / spans, w = std::cos(0.5 * step);
  std::vector<Vec3> pts;
  std::vector<double> weights, knots = {0, 0, 0};
  for (int s = 0; s < spans; ++s) {
    const double a0 = start + s * step, am = a0 + 0.5 * step;
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

double occupiedVolume(const voxel::Rasterization& r, const PrinterGrid& g) {
  return double(r.grid->activeVoxelCount()) * g.voxelVolume();
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

TEST_CASE("E within 1e-6 of the exact E along curved rods", "[voxel][values]") {
  // The swept pieces' E (rod_pieces.hpp) is measured to 1e-6 relative; every active voxel against the
  // exact rule, where E changes along rods whose curvature changes too (the bowed lattice's rods, a
  // helix with a quadratic E, a strip whose E swings between its bounds). The voxel holds a float:
  // its rounding (2^-24 relative) comes on top.
  examples::LatticeParameters p;
  p.nodes = Eigen::Vector3i(3, 3, 3);
  p.rodDiameter = 0.8;
  p.bow = 0.15;
  const BSplineField e3(2, {0, 0, 0, 0.5, 1, 1, 1}, {8.0, 150.0, 40.0, 90.0});
  const BSplineField swing(3, {0, 0, 0, 0, 0.3, 0.6, 1, 1, 1, 1}, {8, 8, 190, 190, 8, 8});
  // The wide strip along a gentle arc takes E's cubic term where its field has knots inside a piece,
  // whose error peaks between the sections the term is fitted to (rod_pieces.cpp, modulusErrorBetween).
  const double angle = 1.2, start = 0.5 * kPi - 0.5 * angle;
  const std::vector<std::pair<RodStructure, openvdb::Vec3d>> designs{
      {examples::cubicLatticeScaledTo({4.0, 4.0, 4.5}, p), {0.05, 0.06, 0.04}},
      {design({circularRod(helix(1.5, 1.2, 1.0), 0.3, CapStyle::Round, e3),
               Rod("strip", arc(1.2, 0.9 * kPi), Section::rectangle(0.8, 0.3), Vec3(0, 0, 1), std::nullopt, CapStyle::Flat, swing)}),
       kTestVoxel},
      {design({Rod("wide strip", arc(8.0, angle, Vec3::Zero(), start), Section::rectangle(1.2, 0.5), Vec3(0, 0, 1), std::nullopt,
                   CapStyle::Flat, swing)}),
       kTestVoxel},
  };
  for (const auto& [s, voxelSize] : designs) {
    const PrinterGrid g = voxel::makePrinterGrid(s, voxelSize);
    const voxel::Rasterization ras = voxel::rasterize(s, g);
    double worst = 0.0;
    std::size_t checked = 0;
    for (auto it = ras.grid->cbeginValueOn(); it; ++it) {
      const ExactVoxel e = exactVoxel(s, world(g, it.getCoord()));
      REQUIRE(e.inside);
      if (e.depth - e.runnerUpDepth <= 1e-6) continue;  // a near tie may go either way (requireMatchesExactTest)
      worst = std::max(worst, std::abs(double(*it) - e.value) / std::abs(e.value));
      ++checked;
    }
    INFO(s.rods.front().name() << ": " << checked << " voxels, worst relative E difference " << worst);
    CHECK(checked > 20000);
    CHECK(worst <= 1e-6 + std::ldexp(1.0, -24));
  }
}

TEST_CASE("On a circular arc the swept pieces follow the turning sections within their bound, pieces longer than the blend allows", "[voxel][pieces]") {
  // Off the axis the blend of the coordinates measured in a piece's two planes misses by about
  // x theta^2 lambda (1 - lambda) / 2 (theta = L / R, x the coordinate in the plane of the bend): with
  // the quadratic term alone, which is fitted on the axis, a piece within kCoordinateTolerance (the
  // measured error doubled) is at most R sqrt(4 tolerance / x) long. The terms across hold that error:
  // points p = r(u) + x1 d1(u) + x2 d2(u) of the elliptic section, whose frame coordinates are (x1, x2)
  // by construction, estimated within each piece's stated bound coordinate by coordinate (a sign or a
  // swap of the terms would show), and the pieces are fewer than half what the blend alone would need
  // (counted with the smaller half axis, the fewest). The arc runs along x (its tangents within 0.6 rad
  // of it), where the voxel loop's rows are short and whole pieces with the terms cost less than halves
  // without them (halvesCostLess, rod_pieces.cpp).
  const double R = 8.0, halfWidth = 0.6, halfHeight = 0.4, angle = 1.2, start = 0.5 * kPi - 0.5 * angle;
  const RodStructure s = design({Rod("arc", arc(R, angle, Vec3::Zero(), start), Section::ellipse(2 * halfWidth, 2 * halfHeight),
                                     Vec3(0, 0, 1), std::nullopt, CapStyle::Round, BSplineField::constant(50, 0, 1))});
  const Rod& rod = s.rods[0];
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const voxel::detail::RodPieces rp = voxel::detail::buildRodPieces(rod, g);
  const auto at = [&](const voxel::detail::AffineInIndex& f, const Vec3& p) {
    const Vec3 q((p.x() - g.origin.x()) / g.voxelSize.x(), (p.y() - g.origin.y()) / g.voxelSize.y(), (p.z() - g.origin.z()) / g.voxelSize.z());
    return f.c + f.gx * q.x() + f.gy * q.y() + f.gz * q.z();
  };
  std::size_t swept = 0, withTerms = 0, checked = 0;
  for (const voxel::detail::RodPiece& piece : rp.pieces) {
    if (piece.kind != voxel::detail::RodPiece::Kind::Swept) continue;
    ++swept;
    withTerms += voxel::detail::needsFullEstimate(piece);
  }
  // An ellipse's gauge bound is sqrt 2 times the coordinate bound over the smaller half axis (rod_pieces.cpp, addSwept).
  const double gaugePerCoordinate = std::sqrt(2.0) / halfHeight;
  double worstShare = 0.0;  // the largest coordinate error over the piece's stated bound
  std::uint64_t h = 0x9e3779b97f4a7c15ull;
  const auto uniform = [&] {
    h ^= h << 13, h ^= h >> 7, h ^= h << 17;
    return static_cast<double>(h >> 11) * 0x1p-53;
  };
  const NurbsCurve& c = rod.centerline();
  for (int n = 0; n < 40000; ++n) {
    const double u = c.domainBegin() + (c.domainEnd() - c.domainBegin()) * uniform();
    const double rho = std::sqrt(uniform()), psi = 2.0 * kPi * uniform();
    const double x1 = halfWidth * rho * std::cos(psi), x2 = halfHeight * rho * std::sin(psi);
    const geometry::Frame f = rod.frame().at(c, u);
    const Vec3 p = c.point(u) + x1 * f.d1 + x2 * f.d2;
    for (const voxel::detail::RodPiece& piece : rp.pieces) {
      if (piece.kind != voxel::detail::RodPiece::Kind::Swept) continue;
      const auto& A = rp.planes[static_cast<std::size_t>(piece.plane)];
      const auto& B = rp.planes[static_cast<std::size_t>(piece.plane) + 1];
      const double a = at(A, p), b = at(B, p);
      if (!(a >= 0.0 && b < 0.0)) continue;
      const auto e = voxel::detail::estimateSwept(piece, a, b, at(piece.x1Begin, p), at(piece.x2Begin, p), at(piece.x1End, p), at(piece.x2End, p));
      const double error = std::max(std::abs(e.x1 - x1), std::abs(e.x2 - x2));
      worstShare = std::max(worstShare, error * gaugePerCoordinate / piece.normalizedRadiusErrorBound);
      ++checked;
    }
  }
  const double blendAlone = R * angle / (R * std::sqrt(4.0 * voxel::detail::kCoordinateTolerance / halfHeight));
  INFO(swept << " swept pieces (" << withTerms << " with the terms), " << checked << " points, worst error " << worstShare
             << " of the bound; the blend alone: " << blendAlone << " pieces at least");
  CHECK(checked == 40000);  // the slabs of neighbouring pieces share their planes: each point lies in one
  CHECK(worstShare <= 1.0);
  CHECK(withTerms > 0);
  CHECK(double(swept) < 0.5 * blendAlone);
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
  SECTION("round, elliptic and rectangular rods crossing at angles: four neighbours at a time meet filled slots") {
    // The later rods' sure-inside quads land on slots the earlier ones filled: of round rods (the outcome
    // settled four at a time where clear), of a rectangle (whose gauge is not at hand: voxel by voxel),
    // empty and filled slots in one quad at the crossings' edges.
    std::vector<Rod> rods;
    rods.push_back(circularRod(line({-1, 0, 0}, {1, 0, 0}), 0.35, CapStyle::Round, BSplineField::constant(10, 0, 1)));
    rods.emplace_back("bar", line({0.1, -1, 0.05}, {0.1, 1, 0.05}), Section::rectangle(0.5, 0.4), std::nullopt, std::nullopt,
                      CapStyle::Flat, BSplineField::constant(90, 0, 1));
    rods.emplace_back("oval", line({-0.8, -0.7, -0.2}, {0.8, 0.7, 0.25}), Section::ellipse(0.4, 0.25), Vec3(0, 0, 1), std::nullopt,
                      CapStyle::Round, BSplineField::constant(50, 0, 1));
    rods.push_back(circularRod(helix(0.5, 0.6, 1.0), 0.2, CapStyle::Round, BSplineField(1, {0, 0, 1, 1}, {20, 70})));
    const RodStructure s = design(std::move(rods));
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const voxel::Rasterization ras = voxel::rasterize(s, g);
    REQUIRE(requireMatchesExactTest(s, g, ras) > 50000);
    // The four-lane outcomes were taken (else only the voxel-by-voxel rule would have been checked).
    REQUIRE(ras.quadsSettledAtOnce > 0);
    std::uint64_t won = 0;
    for (std::uint64_t v : ras.voxelsPerRod) {
      REQUIRE(v > 0);
      won += v;
    }
    REQUIRE(won == ras.grid->activeVoxelCount());
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

TEST_CASE("The grid is identical for 1 and 2 threads and for any band of layers", "[voxel][determinism]") {
  const RodStructure s = examples::bucklingSpring();
  const PrinterGrid g = voxel::makePrinterGrid(s, {0.08, 0.1, 0.06});
  const voxel::Rasterization one = voxel::rasterize(s, g, {1});
  const voxel::Rasterization two = voxel::rasterize(s, g, {2});
  requireIdentical(*one.grid, *two.grid);
  REQUIRE(one.voxelsPerRod == two.voxelsPerRod);
  REQUIRE(one.exactEvaluations == two.exactEvaluations);
  REQUIRE(one.quadsSettledAtOnce == two.quadsSettledAtOnce);

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

TEST_CASE("Row bounds rounded four at a time as clampToInt(ceil), (floor)", "[voxel][clips]") {
  // The swept loop's FourRows::round: ceilToInts and floorToInts against the scalar rounding, at the
  // clamp's bounds, the int range, integers, halves, signed zeros, infinities and a spread of reals
  // (not NaN, whose conversion to int the scalar side leaves undefined: such rows are marked missed).
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> values = {inf, -inf, 0.0, -0.0, 0.5, -0.5, 3.0, -3.0, 1e-300, -1e-300, 2e9, -2e9,
                                2e9 + 0.5, -2e9 - 0.5, 2e9 - 0.5, -2e9 + 0.5, 2147483647.5, -2147483648.5, 1e300, -1e300};
  std::uint64_t h = 88172645463325252ull;
  for (int n = 0; n < 4000; ++n) {
    h ^= h << 13, h ^= h >> 7, h ^= h << 17;
    const double unit = static_cast<double>(h >> 11) * 0x1p-53 - 0.5;
    values.push_back(unit * std::pow(10.0, n % 12));
  }
  for (std::size_t v = 0; v + 4 <= values.size(); ++v) {
    const voxel::detail::Double4 four{values[v], values[v + 1], values[v + 2], values[v + 3]};
    const voxel::detail::Int4 up = voxel::detail::ceilToInts(four), down = voxel::detail::floorToInts(four);
    for (int l = 0; l < 4; ++l) {
      REQUIRE(up[l] == voxel::detail::clampToInt(std::ceil(four[l])));
      REQUIRE(down[l] == voxel::detail::clampToInt(std::floor(four[l])));
    }
  }
}
