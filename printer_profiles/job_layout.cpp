#include "printer_profiles/job_layout.hpp"

#include "printer_profiles/leaf_bits.hpp"

#include <boost/algorithm/string/join.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

namespace {

int floorToMultiple(int v, int m) { return (v >= 0 ? v / m : -((-v + m - 1) / m)) * m; }
int ceilToMultiple(int v, int m) { return (v + m - 1) / m * m; }

std::string mm(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", v);
  return buf;
}

}  // namespace

JobGeometry planJob(const Profile& profile, const openvdb::CoordBBox& partBounds) {
  if (partBounds.empty()) throw EmptyPartError("the part has no voxels: there is nothing to print");
  const openvdb::Coord dim = partBounds.dim();
  const char* axis[3] = {"x", "y", "z"};
  const std::array<double, 3> partMm = {dim.x() * profile.voxelSizeMm[0], dim.y() * profile.voxelSizeMm[1],
                                        dim.z() * profile.voxelSizeMm[2]};
  std::array<double, 3> overhang{};
  std::vector<std::string> tooLarge;
  for (int a = 0; a < 3; ++a) {
    overhang[a] = std::max(0.0, partMm[a] - profile.trayMm[a]);
    if (overhang[a] > 1e-9)
      tooLarge.push_back("by " + mm(overhang[a]) + " mm along " + axis[a] + " (" + mm(partMm[a]) + " > " +
                         mm(profile.trayMm[a]) + ")");
  }
  if (!tooLarge.empty())
    throw TrayFitError("the part (" + mm(partMm[0]) + " x " + mm(partMm[1]) + " x " + mm(partMm[2]) +
                           " mm) does not fit the " + profile.printer + " tray (" + mm(profile.trayMm[0]) + " x " +
                           mm(profile.trayMm[1]) + " x " + mm(profile.trayMm[2]) + " mm): too large " + boost::algorithm::join(tooLarge, ", "),
                       overhang);

  JobGeometry g;
  g.partBounds = partBounds;
  g.firstColumnI = floorToMultiple(partBounds.min().x() - profile.paddingVoxels[0], 8);
  const int lastI = partBounds.max().x() + profile.paddingVoxels[0];
  g.width = ceilToMultiple(lastI - g.firstColumnI + 1, profile.columnAlignment);
  g.topRowJ = partBounds.max().y() + profile.paddingVoxels[1];
  g.height = dim.y() + 2 * profile.paddingVoxels[1];
  g.firstLayerK = partBounds.min().z();
  g.layers = dim.z();

  const double imageMm[2] = {g.width * profile.voxelSizeMm[0], g.height * profile.voxelSizeMm[1]};
  for (int a = 0; a < 2; ++a)
    if (imageMm[a] > profile.trayMm[a] + 1e-9) {
      std::array<double, 3> over{};
      over[a] = imageMm[a] - profile.trayMm[a];
      throw TrayFitError("the part fits the tray but its image, with the profile's padding and column alignment, is " +
                             mm(imageMm[a]) + " mm along " + axis[a] + ", " + mm(over[a]) + " mm more than the tray's " +
                             mm(profile.trayMm[a]) + " mm; use a profile with less padding",
                         over);
    }
  // A profile read from a file keeps these through its tray (see profile.hpp); one built in code is
  // held to the same maxima here, before any image or preview is allocated.
  const double faces[3] = {double(g.width) * g.height, double(g.width) * g.layers, double(g.height) * g.layers};
  if (g.width > kMaxTrayVoxels || g.height > kMaxTrayVoxels || g.layers > kMaxTrayVoxels ||
      *std::max_element(faces, faces + 3) > static_cast<double>(kMaxTrayFacePixels))
    throw std::invalid_argument("the job's images (" + std::to_string(g.width) + " x " + std::to_string(g.height) + " px, " +
                                std::to_string(g.layers) + " layers) exceed the maxima of " + std::to_string(kMaxTrayVoxels) +
                                " per axis and " + std::to_string(kMaxTrayFacePixels) + " pixels per image or preview face");
  return g;
}

ColumnTops::ColumnTops(const JobGeometry& geometry)
    : geometry_(geometry), width_(geometry.width), height_(geometry.height),
      tops_(static_cast<std::size_t>(geometry.width) * geometry.height, -1), rowMax_(geometry.height, -1) {}

template <typename GridT>
void ColumnTops::includeGrid(const GridT& grid) {
  using LeafT = typename GridT::TreeType::LeafNodeType;
  std::vector<const LeafT*> leaves;
  grid.tree().getNodes(leaves);
  const auto raise = [this](int column, int row, int layer, const openvdb::Coord& ijk) {
    if (column < 0 || column >= width_ || row < 0 || row >= height_ || layer < 0 || layer >= geometry_.layers) {
      std::ostringstream msg;
      msg << "ColumnTops: voxel " << ijk << " lies outside the job's part bounds " << geometry_.partBounds;
      throw std::out_of_range(msg.str());
    }
    std::atomic_ref<std::int32_t> top(tops_[static_cast<std::size_t>(row) * width_ + column]);
    std::int32_t seen = top.load(std::memory_order_relaxed);
    while (seen < layer && !top.compare_exchange_weak(seen, layer, std::memory_order_relaxed)) {
    }
  };
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves.size()), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t n = range.begin(); n != range.end(); ++n) {
      const LeafT& leaf = *leaves[n];
      const openvdb::Coord origin = leaf.origin();
      const LeafBytes active = maskBytes(leaf.getValueMask());
      for (int x = 0; x < 8; ++x)
        for (int y = 0; y < 8; ++y) {
          const std::uint8_t zBits = active.column(x, y);
          if (!zBits) continue;
          const openvdb::Coord ijk(origin.x() + x, origin.y() + y, origin.z() + std::bit_width(zBits) - 1);
          raise(geometry_.column(ijk.x()), geometry_.row(ijk.y()), geometry_.layer(ijk.z()), ijk);
        }
    }
  });
  // Active tiles (a pruned, uniform region) are rare: visit their columns one by one.
  forEachActiveTile(grid.tree(), [&](const openvdb::CoordBBox& box, const auto&) {
    for (int i = box.min().x(); i <= box.max().x(); ++i)
      for (int j = box.min().y(); j <= box.max().y(); ++j) {
        const openvdb::Coord ijk(i, j, box.max().z());
        raise(geometry_.column(i), geometry_.row(j), geometry_.layer(box.max().z()), ijk);
      }
  });
  for (int r = 0; r < height_; ++r)
    rowMax_[r] = *std::max_element(tops_.begin() + static_cast<std::ptrdiff_t>(r) * width_,
                                   tops_.begin() + static_cast<std::ptrdiff_t>(r + 1) * width_);
}

void ColumnTops::include(const openvdb::BoolGrid& grid) { includeGrid(grid); }
void ColumnTops::include(const openvdb::FloatGrid& grid) { includeGrid(grid); }

}  // namespace rodfab::printer_profiles
