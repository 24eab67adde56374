#include "materials/sample_regions.hpp"

#include "materials/ditherer.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rodfab::materials {

namespace {

openvdb::FloatGrid::Ptr emptyFractionGrid(const openvdb::Vec3d& voxelSizeMm) {
  for (int a = 0; a < 3; ++a)
    if (!(voxelSizeMm[a] > 0)) throw std::invalid_argument("sample region: voxel sizes must be > 0 mm");
  auto grid = openvdb::FloatGrid::create(0.0f);
  grid->setName(kFractionGridName);
  grid->setTransform(openvdb::math::Transform::Ptr(
      new openvdb::math::Transform(openvdb::math::MapBase::Ptr(new openvdb::math::ScaleMap(voxelSizeMm)))));
  return grid;
}

void checkFraction(float fraction) {
  if (!(fraction >= 0.0f && fraction <= 1.0f))
    throw std::invalid_argument("sample region: fraction " + std::to_string(fraction) + ", expected [0, 1]");
}

}  // namespace

openvdb::FloatGrid::Ptr makeUniformBlock(const openvdb::Coord& size, float fraction, const openvdb::Vec3d& voxelSizeMm) {
  checkFraction(fraction);
  if (size.x() < 1 || size.y() < 1 || size.z() < 1)
    throw std::invalid_argument("sample region: block size must be at least 1 voxel per axis");
  auto grid = emptyFractionGrid(voxelSizeMm);
  auto acc = grid->getAccessor();
  for (int k = 0; k < size.z(); ++k)
    for (int j = 0; j < size.y(); ++j)
      for (int i = 0; i < size.x(); ++i) acc.setValueOn(openvdb::Coord(i, j, k), fraction);
  return grid;
}

openvdb::FloatGrid::Ptr makeRod(double diameterMm, double lengthMm, int axis, float fraction,
                                const openvdb::Vec3d& voxelSizeMm) {
  checkFraction(fraction);
  if (!(diameterMm > 0) || !(lengthMm > 0)) throw std::invalid_argument("sample region: rod size must be > 0 mm");
  if (axis < 0 || axis > 2) throw std::invalid_argument("sample region: rod axis must be 0 (x), 1 (y) or 2 (z)");
  auto grid = emptyFractionGrid(voxelSizeMm);
  auto acc = grid->getAccessor();
  const double radius = diameterMm / 2;
  const int u = (axis + 1) % 3, v = (axis + 2) % 3;
  const int nu = static_cast<int>(std::ceil(radius / voxelSizeMm[u])), nv = static_cast<int>(std::ceil(radius / voxelSizeMm[v]));
  const int length = static_cast<int>(std::ceil(lengthMm / voxelSizeMm[axis]));
  for (int a = 0; a < length; ++a) {
    if (a * voxelSizeMm[axis] >= lengthMm) break;
    for (int b = -nu; b <= nu; ++b)
      for (int c = -nv; c <= nv; ++c) {
        const double x = b * voxelSizeMm[u], y = c * voxelSizeMm[v];
        if (x * x + y * y > radius * radius) continue;
        openvdb::Coord ijk;
        ijk[axis] = a;
        ijk[u] = b;
        ijk[v] = c;
        acc.setValueOn(ijk, fraction);
      }
  }
  return grid;
}

}  // namespace rodfab::materials
