// The distance from a point to a line segment: the one definition the inside test (rod_classify.cpp),
// the capsule hierarchy (segment_boxes.cpp), the NURBS deviation bound (nurbs.cpp), the rod's sampling
// (rod.cpp) and the rasterizer's pieces (voxel/rod_pieces.cpp) share, so they agree to the bit.
#pragma once

#include "geometry/nurbs.hpp"  // Vec3

#include <algorithm>

namespace rodfab::geometry {

// Distance (mm) from p to the segment [a, b]; to a when a == b. Pure, thread-safe.
inline double distanceToSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

}  // namespace rodfab::geometry
