#include "voxel/printer_grid.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rodfab::voxel {

openvdb::math::Transform::Ptr printerTransform(const openvdb::Vec3d& voxelSizeMm, const openvdb::Vec3d& originMm) {
  openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
  m.setToScale(voxelSizeMm);
  m.setTranslation(originMm);
  return openvdb::math::Transform::createLinearTransform(m);
}

openvdb::CoordBBox PrinterGrid::voxelsWithin(const openvdb::Vec3d& lo, const openvdb::Vec3d& hi) const {
  openvdb::Coord a, b;
  for (int k = 0; k < 3; ++k) {
    const double from = std::ceil((lo[k] - origin[k]) / voxelSize[k]);
    const double to = std::floor((hi[k] - origin[k]) / voxelSize[k]);
    a[k] = static_cast<int>(std::clamp(from, 0.0, double(dims[k])));
    b[k] = static_cast<int>(std::clamp(to, -1.0, double(dims[k] - 1)));
  }
  return {a, b};
}

PrinterGrid makePrinterGrid(const geometry::RodStructure& structure, const openvdb::Vec3d& voxelSizeMm) {
  for (int a = 0; a < 3; ++a)
    if (!(voxelSizeMm[a] > 0.0) || !std::isfinite(voxelSizeMm[a]))
      throw std::invalid_argument("voxel size: expected three positive sizes in mm, got " +
                                  std::to_string(voxelSizeMm[0]) + ", " + std::to_string(voxelSizeMm[1]) + ", " +
                                  std::to_string(voxelSizeMm[2]));
  const geometry::Box3 box = structure.bounds();
  if (structure.rods.empty() || box.isEmpty())
    throw std::invalid_argument(structure.source + ": the design has no rods to voxelize");
  PrinterGrid grid;
  grid.voxelSize = voxelSizeMm;
  for (int a = 0; a < 3; ++a) {
    // Cell (0,0,0) spans [min - voxel, min): centres sit half a voxel off the box's extremes, so
    // the outermost rows sample a rod's surface like a midpoint rule, not tangentially (which
    // loses up to 7 % of a thin rod's volume).
    grid.origin[a] = box.min()[a] - 0.5 * voxelSizeMm[a];
    const double cells = std::ceil((box.max()[a] - box.min()[a]) / voxelSizeMm[a]) + 2.0;
    // The rasterizer packs leaf coordinates into 21 bits per axis.
    if (!(cells <= kMaxVoxelsPerAxis))
      throw std::invalid_argument(structure.source + ": the design spans more than " +
                                  std::to_string(kMaxVoxelsPerAxis) + " voxels along an axis");
    grid.dims[a] = static_cast<int>(cells);
  }
  return grid;
}

}  // namespace rodfab::voxel
