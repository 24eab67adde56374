#include "voxel/grid_statistics.hpp"

#include <openvdb/tree/LeafManager.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <limits>

namespace rodfab::voxel {

GridStatistics computeStatistics(const openvdb::FloatGrid& grid, const PrinterGrid& printerGrid,
                                 std::vector<std::uint64_t> voxelsPerRod) {
  struct Partial {
    std::uint64_t count = 0;
    double sum = 0.0;
    float min = std::numeric_limits<float>::infinity(), max = -std::numeric_limits<float>::infinity();
    openvdb::CoordBBox box;
  };
  openvdb::tree::LeafManager<const openvdb::FloatTree> leaves(grid.tree());
  std::vector<Partial> partials(leaves.leafCount());
  tbb::parallel_for(std::size_t(0), leaves.leafCount(), [&](std::size_t n) {
    Partial& p = partials[n];
    for (auto it = leaves.leaf(n).cbeginValueOn(); it; ++it) {
      const float v = *it;
      ++p.count;
      p.sum += v;
      p.min = std::min(p.min, v);
      p.max = std::max(p.max, v);
      p.box.expand(it.getCoord());
    }
  });
  GridStatistics s;
  s.voxelsPerRod = std::move(voxelsPerRod);
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  double sum = 0.0;
  for (const Partial& p : partials) {
    if (p.count == 0) continue;
    s.activeVoxels += p.count;
    sum += p.sum;
    lo = std::min(lo, p.min);
    hi = std::max(hi, p.max);
    s.boundsVoxels.expand(p.box);
  }
  // Active tiles would be voxels too; the rasterizer never makes them, other producers might.
  auto it = grid.tree().cbeginValueOn();
  it.setMaxDepth(openvdb::FloatTree::ValueOnCIter::LEAF_DEPTH - 1);
  for (; it; ++it) {
    const openvdb::CoordBBox tile = it.getBoundingBox();
    const auto n = static_cast<std::uint64_t>(tile.volume());
    s.activeVoxels += n;
    sum += double(*it) * double(n);
    lo = std::min(lo, *it);
    hi = std::max(hi, *it);
    s.boundsVoxels.expand(tile);
  }
  if (s.activeVoxels == 0) return s;
  s.occupiedVolumeMm3 = double(s.activeVoxels) * printerGrid.voxelVolume();
  s.modulusMin = lo;
  s.modulusMax = hi;
  s.modulusMean = sum / double(s.activeVoxels);
  const openvdb::Vec3d half = 0.5 * printerGrid.voxelSize;
  s.boundsMinMm = printerGrid.worldPoint(s.boundsVoxels.min()) - half;
  s.boundsMaxMm = printerGrid.worldPoint(s.boundsVoxels.max()) + half;
  return s;
}

}  // namespace rodfab::voxel
