// Synthetic "vero_fraction" grids for measuring ditherers: uniform blocks and straight round rods at a
// given voxel size (x, y, z in mm: the printer profile's). Index (i, j, k) maps to (i, j, k) * voxel size in mm.
#pragma once

#include <openvdb/openvdb.h>

namespace rodfab::materials {

// A block of size.x() x size.y() x size.z() voxels from (0, 0, 0), every voxel at `fraction`.
// Throws std::invalid_argument for an empty size or a fraction outside [0, 1].
openvdb::FloatGrid::Ptr makeUniformBlock(const openvdb::Coord& size, float fraction, const openvdb::Vec3d& voxelSizeMm);

// A straight cylinder along `axis` (0 = x, 1 = y, 2 = z) through the index origin: voxels whose centre
// lies within diameterMm / 2 of the axis and 0 <= axial position < lengthMm, every voxel at `fraction`.
openvdb::FloatGrid::Ptr makeRod(double diameterMm, double lengthMm, int axis, float fraction, const openvdb::Vec3d& voxelSizeMm);

}  // namespace rodfab::materials
