// voxel/: kinked, folded and tightly bent rods against a brute-force reference of the solid, extreme
// weights, hostile sizes within their estimates, interruption and the thin-rod warning.
#include "voxel/voxel.hpp"

#include "geometry/geometry.hpp"
#include "tests/voxel_fixture.hpp"

#include <catch2/catch.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <numbers>

using namespace rodfab;
using namespace rodfab::test;  // with the fixture's geometry and voxel names

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

TEST_CASE("A rod coiled tighter than its radius: every voxel as the walk over every segment decides", "[voxel][kink][coil]") {
  // Coil radius 0.2, rod radius 0.6 (and an ellipse): every piece is exact and every voxel is within
  // reach of every turn nearby. The rasterizer's exact test (Rod::classify, nearest segments first)
  // and its once-per-voxel rows must give, voxel by voxel, what the reference walk over every segment
  // gives: membership, and E at the deepest section (E varies along the rod, so the u matters).
  const BSplineField ramp(1, {0, 0, 0.5, 1, 1}, {20, 200, 30});
  const Rod rods[] = {
      circularRod(helix(0.2, 0.063, 3, 21), 0.6, CapStyle::Round, ramp),
      Rod("ellipse", helix(0.25, 0.1, 2, 16), Section::ellipse(1.0, 0.7), Vec3(0, 0, 1), std::nullopt, CapStyle::Flat, ramp),
  };
  for (const Rod& rod : rods) {
    INFO(rod.name());
    const RodStructure s = design({rod});
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const voxel::Rasterization r = voxel::rasterize(s, g);
    REQUIRE(r.exactEvaluations > 0);
    const auto acc = r.grid->getConstAccessor();
    const Vec3 lo = s.bounds().min() - Vec3::Constant(0.1), hi = s.bounds().max() + Vec3::Constant(0.1);
    const openvdb::CoordBBox box = g.voxelsWithin({lo.x(), lo.y(), lo.z()}, {hi.x(), hi.y(), hi.z()});
    std::size_t inside = 0;
    for (auto it = box.begin(); it; ++it) {
      const geometry::RodHit walk = rod.classifyWalkingEverySegment(world(g, *it));
      float value = 0;
      CAPTURE(*it);
      REQUIRE(acc.probeValue(*it, value) == walk.inside);
      if (!walk.inside) continue;
      ++inside;
      REQUIRE(value == Approx(rod.modulus().value(walk.u)).epsilon(1e-6));
    }
    REQUIRE(inside == r.grid->activeVoxelCount());
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
  REQUIRE(e.peakBytes(2, 0) > e.peakBytes(1, 0));  // bounds the heap of a streamed slice: test_materials_mapping.cpp
  REQUIRE(e.peakBytes(0, 0) == e.pieceBytes + e.gridBytes);
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
