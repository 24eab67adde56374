// voxel/: the values voxels carry and the swept pieces' approximation behind them: E at the closest
// centerline point and within 1e-6 of the exact E, within the design's bounds, and the pieces' frame
// coordinates within their stated bound on an arc.
#include "voxel/rod_pieces.hpp"
#include "voxel/voxel.hpp"

#include "examples/example_designs.hpp"
#include "geometry/geometry.hpp"
#include "tests/voxel_fixture.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

using namespace rodfab;
using namespace rodfab::test;  // with the fixture's geometry and voxel names

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
