// The printer-space grid: anisotropic voxels, cell (0,0,0) one voxel below the design's bounding box.
#pragma once

#include "geometry/rod.hpp"

#include <openvdb/openvdb.h>

namespace rodfab::voxel {

// Largest grid extent along one axis (2^24 voxels: 700 m at 600 x 300 dpi).
constexpr int kMaxVoxelsPerAxis = 1 << 24;

// The transform of a printer-space grid: voxel (i, j, k) centred at originMm + (i, j, k) * voxelSizeMm
// (mm; the printer profile's voxel). The only place rodfab builds one: the rasterizer's grids, the
// coupon blocks and the tests all take it from here, and the job writer checks a grid's against its profile.
openvdb::math::Transform::Ptr printerTransform(const openvdb::Vec3d& voxelSizeMm, const openvdb::Vec3d& originMm);

// Voxel (i, j, k) is centred at origin + (i, j, k) * voxelSize (mm); OpenVDB's convention of voxel
// centres at integer index coordinates, so the transform is a plain scale plus translation.
struct PrinterGrid {
  // Voxel size in mm (x, y, z; z the build direction): the printer profile's, the only source of it.
  openvdb::Vec3d voxelSize{0.0, 0.0, 0.0};
  openvdb::Vec3d origin{0.0, 0.0, 0.0};
  // Voxels per axis covering the padded bounding box: indices [0, dims) hold the whole design.
  openvdb::Coord dims{0, 0, 0};

  openvdb::math::Transform::Ptr transform() const { return printerTransform(voxelSize, origin); }
  openvdb::Vec3d worldPoint(const openvdb::Coord& ijk) const {
    return {origin.x() + ijk.x() * voxelSize.x(), origin.y() + ijk.y() * voxelSize.y(),
            origin.z() + ijk.z() * voxelSize.z()};
  }
  // Voxels whose centres lie in the box [lo, hi] (mm), clipped to [0, dims); empty if none.
  openvdb::CoordBBox voxelsWithin(const openvdb::Vec3d& lo, const openvdb::Vec3d& hi) const;
  double voxelVolume() const { return voxelSize.x() * voxelSize.y() * voxelSize.z(); }
  std::uint64_t voxelCount() const {
    return std::uint64_t(dims.x()) * std::uint64_t(dims.y()) * std::uint64_t(dims.z());
  }
};

// The grid for `structure` at `voxelSizeMm` (the printer profile's voxel: x, y, z in mm): the cell of voxel (0,0,0) lies one voxel below the minimum corner of its
// bounding box (its centre half a voxel below), and the cells of [0, dims) reach at least one voxel
// past the maximum, so every design voxel has an empty neighbour on each side. Throws std::invalid_argument when a voxel
// size is not a positive finite number, the design is empty, or it spans more than kMaxVoxelsPerAxis voxels along an
// axis (the message names the axis, the extent and the limit in mm, and the rod, as rods[i] and its name, with the
// field that makes it that long: its section or its control points; or the two rods reaching lowest and highest).
// Thread-safe (pure).
PrinterGrid makePrinterGrid(const geometry::RodStructure& structure, const openvdb::Vec3d& voxelSizeMm);

}  // namespace rodfab::voxel
