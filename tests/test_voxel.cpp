// voxel/: rasterization against analytic volumes, the exact per-voxel test, and itself (threads, bands).
#include "voxel/voxel.hpp"
#include "voxel/raster_clips.hpp"

#include "examples/example_designs.hpp"
#include "geometry/geometry.hpp"
#include "tests/voxel_fixture.hpp"

#include <catch2/catch.hpp>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

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
  SECTION("the benchmark lattices, straight and curved, at a smaller scale - 6-rod joints with round caps") {
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
  SECTION("identical rods: the first one takes every voxel, the copies cost no exact test") {
    const Rod a = circularRod(helix(1.0, 0.8, 0.5), 0.3, CapStyle::Round, BSplineField::constant(33, 0, 1));
    const Rod b = circularRod(helix(1.0, 0.8, 0.5), 0.3, CapStyle::Round, BSplineField::constant(77, 0, 1));
    const RodStructure s = design({a, b, b});
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const voxel::Rasterization ras = voxel::rasterize(s, g);
    REQUIRE(ras.voxelsPerRod[1] == 0);
    REQUIRE(ras.voxelsPerRod[2] == 0);
    REQUIRE(ras.voxelsPerRod[0] == ras.grid->activeVoxelCount());
    for (auto it = ras.grid->cbeginValueOn(); it; ++it) REQUIRE(*it == 33.0f);
    // As the first rod alone, to the exact tests made: every voxel of a copy ties, and a tie was only
    // settled by the exact test (each copy of a 20 mm rod cost 49 ms).
    const voxel::Rasterization alone = voxel::rasterize(design({a}), g);
    requireIdentical(*alone.grid, *ras.grid);
    REQUIRE(ras.exactEvaluations == alone.exactEvaluations);
    // A rod that differs from the first only a little (its radius) is no copy: it wins the shell around it.
    const RodStructure wider = design({a, b, circularRod(helix(1.0, 0.8, 0.5), 0.35, CapStyle::Round)});
    const voxel::Rasterization shell = voxel::rasterize(wider, g);
    REQUIRE(shell.voxelsPerRod[2] > 0);
    requireMatchesExactTest(wider, g, shell);
  }
}

TEST_CASE("Rods listed twice a hair apart: the same E settles their ties without the exact test", "[voxel][overlap]") {
  // A control point 1e-9 mm off: no copy (solidKey), so every voxel the two share is a near tie.
  const NurbsCurve c = helix(1.0, 0.8, 0.5);
  std::vector<Vec3> moved = c.points();
  moved[2].x() += 1e-9;
  const NurbsCurve nearCopy(c.degree(), c.knots(), moved);
  const Rod a = circularRod(c, 0.3, CapStyle::Round, BSplineField::constant(33, 0, 1));
  const RodStructure same = design({a, circularRod(nearCopy, 0.3, CapStyle::Round, BSplineField::constant(33, 0, 1))});
  const PrinterGrid g = voxel::makePrinterGrid(same, kTestVoxel);
  const voxel::Rasterization alone = voxel::rasterize(design({a}), g);
  const voxel::Rasterization twice = voxel::rasterize(same, g);
  requireMatchesExactTest(same, g, twice);
  for (auto it = twice.grid->cbeginValueOn(); it; ++it) REQUIRE(*it == 33.0f);
  REQUIRE(twice.grid->activeVoxelCount() == alone.grid->activeVoxelCount());
  // Ties go to the lower rod; only the shells where membership is in doubt are tested again: the
  // copy adds at most as many exact tests as the rod alone made (it made one per voxel shared before).
  REQUIRE(twice.voxelsPerRod[0] > 0.99 * double(twice.grid->activeVoxelCount()));
  REQUIRE(twice.exactEvaluations <= 2 * alone.exactEvaluations);
  REQUIRE(twice.exactEvaluations < twice.grid->activeVoxelCount() / 4);
  // With another E the winner matters: the near ties go to the exact test, and match it.
  const RodStructure other = design({a, circularRod(nearCopy, 0.3, CapStyle::Round, BSplineField::constant(77, 0, 1))});
  const voxel::Rasterization differing = voxel::rasterize(other, g);
  requireMatchesExactTest(other, g, differing);
  REQUIRE(differing.exactEvaluations > twice.grid->activeVoxelCount() / 2);
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

  // Called in a TBB context being cancelled (a pipeline's stage after another one threw): none of its
  // parallel loops is skipped, the grid is whole. With threads 0 (the caller's arena's, as the slicer's
  // stage calls it) whatever the machine's core count.
  const voxel::Rasterizer onCallersArena(s, g, {0});
  tbb::task_group_context cancelling;
  voxel::Rasterization inCancelled;
  tbb::parallel_for(0, 1, [&](int) {
    cancelling.cancel_group_execution();
    inCancelled = onCallersArena.rasterizeLayers(0, g.dims.z());
  }, cancelling);
  REQUIRE(cancelling.is_group_execution_cancelled());
  requireIdentical(*inCancelled.grid, *one.grid);
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
