// Where a part's voxels land in a job's images: the image frame (bounding box, padding, column
// alignment, row order), the tray check, and the column-top map the explicit support policy needs.
#pragma once

#include "printer_profiles/profile.hpp"

#include <openvdb/openvdb.h>

#include <array>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace rodfab::printer_profiles {

// Voxel (i, j, k) of a printer-space grid is pixel (column, row) of layer image `layer`:
//   column = i - firstColumnI          (x grows to the right)
//   row    = topRowJ - j               (row 0 is the largest y: see Profile::rowOrder)
//   layer  = k - firstLayerK           (layer 0 is the part's lowest layer, on the tray)
struct JobGeometry {
  openvdb::CoordBBox partBounds;  // every model voxel, index space
  int width = 0, height = 0, layers = 0;
  int firstColumnI = 0, topRowJ = 0, firstLayerK = 0;

  int column(int i) const { return i - firstColumnI; }
  int row(int j) const { return topRowJ - j; }
  int layer(int k) const { return k - firstLayerK; }
  int i(int column) const { return firstColumnI + column; }
  int j(int row) const { return topRowJ - row; }
  int k(int layer) const { return firstLayerK + layer; }
};

// A part that does not fit the tray. overhangMm[a] > 0 on every axis where it is too large.
class TrayFitError : public std::runtime_error {
public:
  TrayFitError(const std::string& message, std::array<double, 3> overhangMm)
      : std::runtime_error(message), overhangMm_(overhangMm) {}
  const std::array<double, 3>& overhangMm() const { return overhangMm_; }

private:
  std::array<double, 3> overhangMm_;
};

// A part without a single voxel: nothing to print.
class EmptyPartError : public std::invalid_argument {
public:
  using std::invalid_argument::invalid_argument;
};

// Images cover the part's bounding box plus the profile's padding, widened to the column alignment.
// The first column sits on a multiple of 8 in i so that each 8-voxel OpenVDB leaf row fills exactly
// one image byte. Throws TrayFitError (naming each axis and by how many mm) when the part, or its
// padded image, does not fit the tray; EmptyPartError for an empty box; std::invalid_argument for images beyond the
// maxima a profile file is held to (kMaxTrayVoxels, kMaxTrayFacePixels: only a profile built in code
// can get there).
JobGeometry planJob(const Profile& profile, const openvdb::CoordBBox& partBounds);

// For every image pixel, the layer of the highest model voxel in that column (-1: none).
// Explicit support fills a column from the tray up to its highest model voxel wherever the model
// is absent, so this map must be complete before the first band is encoded: build it in a cheap
// pre-pass over the active topology of the whole part (the modulus grid from voxel/ or the material
// grid), band by band if need be; only leaf masks are read, not values.
class ColumnTops {
public:
  explicit ColumnTops(const JobGeometry& geometry);

  // Raises the map by every active voxel of `grid` (voxels outside the image are an error).
  void include(const openvdb::BoolGrid& grid);
  void include(const openvdb::FloatGrid& grid);

  int top(int column, int row) const { return tops_[static_cast<std::size_t>(row) * width_ + column]; }
  int width() const { return width_; }
  int height() const { return height_; }
  // The highest top in each image row, so layers above it skip the row.
  const std::vector<std::int32_t>& rowMaximum() const { return rowMax_; }

private:
  template <typename GridT>
  void includeGrid(const GridT& grid);

  JobGeometry geometry_;
  int width_ = 0, height_ = 0;
  std::vector<std::int32_t> tops_;
  std::vector<std::int32_t> rowMax_;
};

}  // namespace rodfab::printer_profiles
