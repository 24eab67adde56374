// How well a dithered region reproduces its fractions: bias, low-pass error in physical units,
// clustering of the rigid phase and run lengths.
//
// The region is the active voxels of the "vero_fraction" grid; the "material" grid must have exactly
// the same active voxels. The metrics work on a dense copy of the region's bounding box (a few bytes
// per cell), so they are meant for test pieces and reports, not whole print jobs; boxes over 2^30
// cells are refused.
#pragma once

#include <openvdb/openvdb.h>

#include <array>
#include <cstddef>

namespace rodfab::materials {

struct DitherQuality {
  std::size_t voxels = 0;      // in the region
  std::size_t veroVoxels = 0;
  double targetMean = 0.0;     // mean fraction asked for
  double achievedMean = 0.0;   // share of Vero voxels
  double meanBias = 0.0;       // achievedMean - targetMean
  double lowPassRms100um = 0.0;  // lowPassErrorRms at sigma 0.100 mm
  double lowPassRms250um = 0.0;  // lowPassErrorRms at sigma 0.250 mm
  // Share of the Vero voxels that lie in the largest face-connected cluster of Vero voxels (0 when
  // there is no Vero): near 1 means the rigid phase percolates as one network.
  double largestVeroClusterShare = 0.0;
  // Mean length, in voxels, of maximal runs of one material along x, y and z inside the region (a run
  // also ends where the region does).
  std::array<double, 3> meanRunLength{0.0, 0.0, 0.0};
};

// Throws std::invalid_argument when the grids' active voxels differ or the region is too large, and
// common::Interrupted on SIGINT / SIGTERM (the low-pass convolutions poll it per chunk of lines).
DitherQuality measureDitherQuality(const openvdb::FloatGrid& fraction, const openvdb::BoolGrid& material);

// RMS over the region of the low-passed error: with e = material - fraction and m = 1 inside the
// region, 0 outside, the low-passed error at voxel x is sum_y G(x - y) m(y) e(y) / sum_y G(x - y) m(y),
// G a Gaussian with standard deviation `sigmaMm` in every physical direction (sigmaMm / voxel size
// voxels per axis, taken from the grid's transform, truncated at 4 sigma). Normalizing over the region
// means voxels outside the part neither count as error nor dilute it near boundaries.
double lowPassErrorRms(const openvdb::FloatGrid& fraction, const openvdb::BoolGrid& material, double sigmaMm);

}  // namespace rodfab::materials
