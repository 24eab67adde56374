// How much memory a whole-design rasterization will take, known before the first voxel is made.
#pragma once

#include "geometry/rod.hpp"
#include "voxel/printer_grid.hpp"

#include <cstdint>

namespace rodfab::voxel {

// Resident bytes of the grid `rasterize(structure, grid)` builds (voxel/rasterize.hpp), estimated from
// the geometry alone: every rod's solid (its section swept along the centerline plus the caps) widened
// by half a tree node's diagonal, in leaf nodes (8^3 voxels) and the internal nodes above them (128^3 and
// 4096^3), times the bytes each takes. Overlaps at joints are counted once per rod, so the estimate errs
// high there. Measured (resident memory of `rodfab voxelize`): a solid 15 mm rod, 65.8 M voxels, 359 MiB
// against 369 MiB estimated; a 20 mm rod 0.99 GiB against 1.1 GiB; the lattice benchmark class (1,520 rods
// meeting at joints) 1.9 GiB against 3.6 GiB. Thread-safe; never throws; UINT64_MAX when beyond range.
std::uint64_t estimateRasterizationBytes(const geometry::RodStructure& structure, const PrinterGrid& grid);

// Volume (mm^3) of the rod's solid widened by `margin` mm on every side: the Steiner formula for the
// section (exact for the convex sections rods have) times the centerline length, with each cap and the
// margin as extra length. The tree nodes of size s a rod touches fit in its solid widened by half a
// node's diagonal. Thread-safe.
double widenedRodVolume(const geometry::Rod& rod, double margin);

}  // namespace rodfab::voxel
