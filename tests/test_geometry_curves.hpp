// Curves the geometry tests share (test_geometry.cpp, test_geometry_classify.cpp).
#pragma once
#include "geometry/nurbs.hpp"

#include <cmath>
#include <numbers>
#include <vector>

namespace rodfab::geometry::testing {

// A helix as a dense interpolating-ish cubic B-spline (control points on a slightly larger helix).
inline NurbsCurve helix(double radius, double pitch, double turns, int pointsPerTurn = 16) {
  const int n = static_cast<int>(turns * pointsPerTurn) + 1;
  std::vector<Vec3> pts;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * std::numbers::pi * i / pointsPerTurn;
    pts.emplace_back(radius * std::cos(a), radius * std::sin(a), pitch * a / (2 * std::numbers::pi));
  }
  std::vector<double> knots(4, 0.0);
  for (int i = 1; i < n - 3; ++i) knots.push_back(static_cast<double>(i) / (n - 3));
  knots.insert(knots.end(), 4, 1.0);
  return NurbsCurve(3, knots, pts);
}

}  // namespace rodfab::geometry::testing
