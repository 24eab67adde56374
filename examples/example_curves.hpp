// Curve, field and rod builders shared by the example and benchmark designs (internal to examples/).
#pragma once

#include "geometry/rod.hpp"

#include <array>
#include <cstddef>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

namespace rodfab::examples::detail {

inline constexpr double kPi = std::numbers::pi;

// The straight segment from a to b (degree 1).
geometry::NurbsCurve straight(const geometry::Vec3& a, const geometry::Vec3& b);

// Control points of the cubic Bezier that passes through s[0..3] at t = 0, 1/3, 2/3, 1.
template <class T>
std::vector<T> bezierThrough(const std::array<T, 4>& s) {
  return {s[0], T((-5.0 * s[0] + 18.0 * s[1] - 9.0 * s[2] + 2.0 * s[3]) / 6.0),
          T((2.0 * s[0] - 9.0 * s[1] + 18.0 * s[2] - 5.0 * s[3]) / 6.0), s[3]};
}

// The cubic Bezier through q(0), q(1/3), q(2/3), q(1).
geometry::NurbsCurve cubicThrough(const std::function<geometry::Vec3(double)>& q);

// Cubic quaternion spline through four samples of a rotation path (kept in one hemisphere, since
// q and -q are the same rotation but would interpolate through zero).
geometry::QuaternionSpline quaternionsThrough(const std::function<Eigen::Vector4d(double)>& q);

// Circular arc about the z axis at height z, from angle a0 to a1 (|a1 - a0| < pi): one rational
// quadratic span, exact.
geometry::NurbsCurve ringArc(double radius, double a0, double a1, double z);

// Piecewise-linear E(s) through the start, middle and end values.
geometry::BSplineField threePointModulus(double start, double middle, double end);

// prefix followed by i in three digits at least ("x007").
std::string numbered(const std::string& prefix, std::size_t i);

// A round-capped rod of circular cross-section `diameter` (mm).
geometry::Rod circleRod(std::string name, geometry::NurbsCurve curve, double diameter, geometry::BSplineField modulus);

}  // namespace rodfab::examples::detail
