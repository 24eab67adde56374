// Summary figures of a rasterized modulus grid.
#pragma once

#include "voxel/printer_grid.hpp"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <vector>

namespace rodfab::voxel {

struct GridStatistics {
  std::uint64_t activeVoxels = 0;
  double occupiedVolumeMm3 = 0.0;  // active voxels times the voxel volume
  double modulusMin = 0.0, modulusMean = 0.0, modulusMax = 0.0;  // MPa over active voxels (0 if none)
  openvdb::CoordBBox boundsVoxels;  // index bounds of the active voxels (empty if none)
  openvdb::Vec3d boundsMinMm{0.0}, boundsMaxMm{0.0};  // outer faces of those voxels, mm
  std::vector<std::uint64_t> voxelsPerRod;
};

// Deterministic: sums are taken leaf by leaf in tree order whatever the thread count.
GridStatistics computeStatistics(const openvdb::FloatGrid& grid, const PrinterGrid& printerGrid,
                                 std::vector<std::uint64_t> voxelsPerRod = {});

}  // namespace rodfab::voxel
