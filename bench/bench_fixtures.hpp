// Shared by the benchmarks of the design half (bench_mechanics, bench_optimize): the process's peak
// memory, and the training load the published examples use.
#pragma once

#include "geometry/rod.hpp"
#include "mechanics/mechanics_spec.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

namespace rodfab::bench {

// The process's peak resident memory in MiB (getrusage's ru_maxrss).
inline double peakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

// The lowest and highest `axis` coordinate (0 x, 1 y, 2 z) of the rods' end points.
inline std::pair<double, double> endRange(const std::vector<geometry::Rod>& rods, int axis) {
  double lo = 1e300, hi = -1e300;
  for (const auto& r : rods)
    for (const geometry::Vec3& p : {r.centerline().points().front(), r.centerline().points().back()})
      lo = std::min(lo, p[axis]), hi = std::max(hi, p[axis]);
  return {lo, hi};
}

// A training load of the kind the published examples use: a support clamping every rod end at the
// lowest `axis` coordinate and one moving every end at the highest by `displacement` (mm), within
// 1e-6 of the ends' extent; one support per point (ends that meet, to 0.1 um, share it).
inline std::vector<mechanics::Support> trainingSupports(const std::vector<geometry::Rod>& rods, int axis,
                                                        const geometry::Vec3& displacement) {
  const auto [lo, hi] = endRange(rods, axis);
  const double tol = 1e-6 * (hi - lo);
  auto key = [](const geometry::Vec3& p) {
    return std::make_tuple(std::llround(p.x() * 1e4), std::llround(p.y() * 1e4), std::llround(p.z() * 1e4));
  };
  std::set<std::tuple<long long, long long, long long>> seen;
  std::vector<mechanics::Support> supports;
  for (const auto& r : rods)
    for (const geometry::Vec3& p : {r.centerline().points().front(), r.centerline().points().back()}) {
      const bool low = p[axis] < lo + tol, high = p[axis] > hi - tol;
      if ((!low && !high) || !seen.insert(key(p)).second) continue;
      mechanics::Support support;
      support.at.point = p;
      support.at.path = "bench";
      if (high) support.displacement = displacement;
      supports.push_back(support);
    }
  return supports;
}

}  // namespace rodfab::bench
