#include "voxel/memory_estimate.hpp"

#include "common/memory_budget.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>

namespace rodfab::voxel {

namespace {

// A float leaf node (8^3 voxels): 512 values (2 KiB), masks and its share of the allocator; measured on
// solid parts as 4.5 to 4.7 bytes a voxel of resident memory.
constexpr double kLeafVoxels = 8.0, kBytesPerLeaf = 4.6 * 512.0;
// The internal nodes above the leaves hold a table of 16^3 and 32^3 child pointers and their masks:
// a fixed cost for every 128^3 and 4096^3 block of voxels the part reaches, which dominates thin parts.
constexpr double kLowerVoxels = 128.0, kBytesPerLower = 4096.0 * 8.0 + 2.0 * 512.0;
constexpr double kUpperVoxels = 4096.0, kBytesPerUpper = 32768.0 * 8.0 + 2.0 * 4096.0;

// How many tree nodes of `nodeVoxels`^3 voxels the design reaches: its rods widened by half a node's
// diagonal, in nodes, at most the nodes the envelope spans (nodes are aligned to multiples of their size
// in index space, and the envelope's indices start at 0).
double nodesReached(const geometry::RodStructure& structure, const PrinterGrid& grid, double nodeVoxels) {
  const openvdb::Vec3d node = grid.voxelSize * nodeVoxels;
  double nodes = 0.0;
  for (const geometry::Rod& rod : structure.rods) nodes += widenedRodVolume(rod, 0.5 * node.length()) / (node.x() * node.y() * node.z());
  double spanned = 1.0;
  for (int a = 0; a < 3; ++a) spanned *= std::ceil(double(grid.dims[a]) / nodeVoxels);
  return std::min(nodes, spanned);
}

}  // namespace

double widenedRodVolume(const geometry::Rod& rod, double margin) {
  const geometry::Section& s = rod.section();
  const double area = s.area() + s.perimeter() * margin + std::numbers::pi * margin * margin;
  const double capLength = rod.caps() == geometry::CapStyle::Round ? s.capRadius() : 0.0;
  return area * (rod.length() + 2.0 * (capLength + margin));
}

std::uint64_t estimateRasterizationBytes(const geometry::RodStructure& structure, const PrinterGrid& grid) {
  const double bytes = nodesReached(structure, grid, kLeafVoxels) * kBytesPerLeaf +
                       nodesReached(structure, grid, kLowerVoxels) * kBytesPerLower +
                       nodesReached(structure, grid, kUpperVoxels) * kBytesPerUpper;
  return common::saturatedBytes(bytes);
}

}  // namespace rodfab::voxel
