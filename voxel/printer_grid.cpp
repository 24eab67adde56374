#include "voxel/printer_grid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace rodfab::voxel {

namespace {

const char* axisName(int a) { return a == 0 ? "x" : a == 1 ? "y" : "z"; }

std::string mm(double value) {
  // An extent of rods near the double's range overflows: say so rather than print "inf mm".
  if (std::isinf(value)) return value < 0 ? "below -1.8e+308 mm" : "more than 1.8e+308 mm";
  char text[40];
  std::snprintf(text, sizeof text, "%.6g mm", value);
  return text;
}

double extentAlong(const geometry::Box3& box, int a) { return box.max()[a] - box.min()[a]; }

// A rod as the design file identifies it: its index in `rods` and its name.
std::string rodLabel(const geometry::RodStructure& structure, std::size_t r) {
  return "rods[" + std::to_string(r) + "] (\"" + structure.rods[r].name() + "\")";
}

// The field of a rod that makes it `extentMm` long along axis a: its section when that is wider than its
// control points spread along a (the rod reaches about half its section past them on each side), else the
// control points lowest and highest along a (the centerline stays within their hull).
std::string rodSpanCause(const geometry::Rod& rod, int a) {
  const std::vector<geometry::Vec3>& points = rod.centerline().points();
  std::size_t lo = 0, hi = 0;
  for (std::size_t p = 1; p < points.size(); ++p) {
    if (points[p][a] < points[lo][a]) lo = p;
    if (points[p][a] > points[hi][a]) hi = p;
  }
  const geometry::Section& section = rod.section();
  if (2.0 * section.boundingRadius() > points[hi][a] - points[lo][a]) {
    if (section.shape == geometry::SectionShape::Circle) return "its section.diameter of " + mm(section.width);
    return section.width >= section.height ? "its section.width of " + mm(section.width) : "its section.height of " + mm(section.height);
  }
  const std::string along = std::string(" at ") + axisName(a) + " = ";
  return "its control points centerline.points[" + std::to_string(lo) + "]" + along + mm(points[lo][a]) +
         " and centerline.points[" + std::to_string(hi) + "]" + along + mm(points[hi][a]);
}

// Why the design spans more than `limitMm` along axis a, naming the rod(s) and field: the rod longest
// along a when it alone is over the limit, else the rods reaching lowest and highest.
std::string designSpanCause(const geometry::RodStructure& structure, int a, double limitMm) {
  std::size_t longest = 0, lowest = 0, highest = 0;
  for (std::size_t r = 1; r < structure.rods.size(); ++r) {
    const geometry::Box3 box = structure.rods[r].bounds();
    if (extentAlong(box, a) > extentAlong(structure.rods[longest].bounds(), a)) longest = r;
    if (box.min()[a] < structure.rods[lowest].bounds().min()[a]) lowest = r;
    if (box.max()[a] > structure.rods[highest].bounds().max()[a]) highest = r;
  }
  const geometry::Rod& rod = structure.rods[longest];
  if (!(extentAlong(rod.bounds(), a) <= limitMm))
    return rodLabel(structure, longest) + " spans " + mm(extentAlong(rod.bounds(), a)) + " along " + axisName(a) + " (" +
           rodSpanCause(rod, a) + ")";
  return rodLabel(structure, lowest) + " reaches down to " + axisName(a) + " = " + mm(structure.rods[lowest].bounds().min()[a]) +
         " and " + rodLabel(structure, highest) + " up to " + axisName(a) + " = " + mm(structure.rods[highest].bounds().max()[a]);
}

}  // namespace

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
    // The rasterizer packs leaf coordinates into 21 bits per axis. Past the limit the message names
    // the rod and the field that make the design that long (a diameter or a control point typed
    // wrong, or in metres), and the extent in mm this printer's voxel allows.
    if (!(cells <= kMaxVoxelsPerAxis)) {
      const double limitMm = double(kMaxVoxelsPerAxis - 2) * voxelSizeMm[a];  // a voxel of padding each side
      throw std::invalid_argument(structure.source + ": the design spans " + mm(box.max()[a] - box.min()[a]) + " along " +
                                  axisName(a) + ": " + designSpanCause(structure, a, limitMm) + "; expected at most " +
                                  mm(limitMm) + " along " + axisName(a) + " (" + std::to_string(kMaxVoxelsPerAxis) +
                                  " voxels along an axis at this printer's voxel of " + mm(voxelSizeMm[a]) + ")");
    }
    grid.dims[a] = static_cast<int>(cells);
  }
  return grid;
}

}  // namespace rodfab::voxel
