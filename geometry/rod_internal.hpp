// Internal to geometry/: what rod.cpp (the rod's sampling, closest points, bounds) and rod_classify.cpp
// (the inside test, Rod::classify) share.
#pragma once

#include "geometry/nurbs.hpp"
#include "geometry/segment.hpp"

#include <algorithm>
#include <cmath>

namespace rodfab::geometry::detail {

// Safeguarded Newton (Numerical Recipes' rtsafe) for a zero of g on [a, b], where g(a) < 0 < g(b):
// `gAndSlope(u)` returns {g(u), g'(u)}. A Newton step that would leave the bracket, or shrink it
// slower than bisection, is a bisection instead. Returns the zero clamped to [a, b].
template <class GAndSlope>
double safeguardedNewton(double a, double b, GAndSlope gAndSlope) {
  double lo = a, hi = b;
  double u = 0.5 * (a + b);
  double dxOld = b - a, dx = dxOld;
  const double tol = 1e-15 * std::max(1.0, std::abs(b) + std::abs(a));
  for (int it = 0; it < 60; ++it) {
    const auto [g, dg] = gAndSlope(u);
    if (g < 0.0) lo = u; else hi = u;
    const bool newtonOutside = ((u - hi) * dg - g) * ((u - lo) * dg - g) > 0.0;
    const bool newtonSlow = std::abs(2.0 * g) > std::abs(dxOld * dg);
    dxOld = dx;
    if (newtonOutside || newtonSlow || dg <= 0.0) {
      dx = 0.5 * (hi - lo);
      u = lo + dx;
    } else {
      dx = g / dg;
      u -= dx;
    }
    if (std::abs(dx) < tol || g == 0.0) break;
  }
  return std::clamp(u, a, b);
}

// The inside test subdivides segment i when curvature x (gap + deviation + chord) >= 0.5 with a gap
// of at most the section's reach plus the deviation (see classifySegment).
inline constexpr int kFoldSubdivisions = 8;

}  // namespace rodfab::geometry::detail
