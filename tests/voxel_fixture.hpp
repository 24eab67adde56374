// Shared by the voxel tests (tests/test_voxel*.cpp): the test voxel, exact
// and near-exact curves, one-rod designs, a voxel's centre in mm, a bit-for-bit grid comparison and the
// exact per-voxel rule (Rod::classify, deepest rod wins) every rasterized voxel is checked against.
#pragma once

#include "geometry/geometry.hpp"
#include "tests/exact_voxel.hpp"
#include "voxel/voxel.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <utility>
#include <vector>

namespace rodfab::test {

using geometry::BSplineField;
using geometry::CapStyle;
using geometry::NurbsCurve;
using geometry::Rod;
using geometry::RodStructure;
using geometry::Section;
using geometry::Vec3;
using voxel::PrinterGrid;

// The Connex3 profile's voxel (600 x 300 dpi, 30 um layers), which the numbers in these tests assume.
inline const openvdb::Vec3d kTestVoxel(0.0423, 0.0846, 0.030);

inline constexpr double kPi = std::numbers::pi;

inline NurbsCurve line(const Vec3& a, const Vec3& b) { return NurbsCurve(1, {0, 0, 1, 1}, {a, b}); }

// A cubic B-spline with control points on a helix (close to, not exactly, a helix).
inline NurbsCurve helix(double radius, double pitch, double turns, int pointsPerTurn = 12) {
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

// Circular arc of radius R about c in the xy-plane from angle `start` to start + `angle` (angle <= 2 pi),
// exact rational quadratic with one span per quarter turn (at most).
inline NurbsCurve arc(double R, double angle, const Vec3& c = Vec3::Zero(), double start = 0.0) {
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

inline Rod circularRod(NurbsCurve c, double radius, CapStyle caps, BSplineField e = BSplineField::constant(50, 0, 1)) {
  return Rod("rod", std::move(c), Section::circle(2 * radius), std::nullopt, std::nullopt, caps, std::move(e));
}

inline RodStructure design(std::vector<Rod> rods) { return RodStructure{"test", std::move(rods)}; }

inline Vec3 world(const PrinterGrid& g, const openvdb::Coord& c) {
  const openvdb::Vec3d p = g.worldPoint(c);
  return {p.x(), p.y(), p.z()};
}

inline void requireIdentical(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b) {
  REQUIRE(a.activeVoxelCount() == b.activeVoxelCount());
  const auto acc = b.getConstAccessor();
  for (auto it = a.cbeginValueOn(); it; ++it) {
    float v = 0;
    REQUIRE(acc.probeValue(it.getCoord(), v));
    REQUIRE(v == *it);  // bit-identical, not approximately equal
  }
}

// Every voxel of the grid's box: active exactly where the exact test says inside, with E of the
// winning rod at its closest point. Returns the number of voxels checked.
inline std::size_t requireMatchesExactTest(const RodStructure& s, const PrinterGrid& g, const voxel::Rasterization& r,
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

}  // namespace rodfab::test
