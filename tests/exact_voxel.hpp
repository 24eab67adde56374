// The exact per-voxel rule of voxel/rasterize.hpp (Rod::classify, the deepest rod wins, ties to the
// lower index), voxel by voxel: what the voxel tests (voxel_fixture.hpp) and bench/raster_band's
// `verify` check rasterized voxels against.
#pragma once

#include "geometry/rod.hpp"
#include "voxel/rasterize.hpp"

#include <algorithm>
#include <cstddef>

namespace rodfab::test {

// The exact rule, voxel by voxel: deepest rod wins, ties to the lower index.
struct ExactVoxel {
  bool inside = false;
  int rod = -1;
  double depth = -1, runnerUpDepth = -1e300;
  double value = 0;
};
inline ExactVoxel exactVoxel(const geometry::RodStructure& s, const geometry::Vec3& p) {
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

}  // namespace rodfab::test
