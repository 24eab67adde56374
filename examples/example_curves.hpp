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

// The geometry names every example file uses (they say `using namespace detail;`).
using geometry::BSplineField;
using geometry::CapStyle;
using geometry::NurbsCurve;
using geometry::Rod;
using geometry::RodStructure;
using geometry::Section;
using geometry::Vec3;

inline constexpr double kPi = std::numbers::pi;

// The straight segment from a to b (degree 1).
NurbsCurve straight(const Vec3& a, const Vec3& b);

// Control points of the cubic Bezier that passes through s[0..3] at t = 0, 1/3, 2/3, 1.
template <class T>
std::vector<T> bezierThrough(const std::array<T, 4>& s) {
  return {s[0], T((-5.0 * s[0] + 18.0 * s[1] - 9.0 * s[2] + 2.0 * s[3]) / 6.0),
          T((2.0 * s[0] - 9.0 * s[1] + 18.0 * s[2] - 5.0 * s[3]) / 6.0), s[3]};
}

// The cubic Bezier through q(0), q(1/3), q(2/3), q(1).
NurbsCurve cubicThrough(const std::function<Vec3(double)>& q);

// Cubic quaternion spline through four samples of a rotation path (kept in one hemisphere, since
// q and -q are the same rotation but would interpolate through zero).
geometry::QuaternionSpline quaternionsThrough(const std::function<Eigen::Vector4d(double)>& q);

// Circular arc about the z axis at height z, from angle a0 to a1 (|a1 - a0| < pi): one rational
// quadratic span, exact.
NurbsCurve ringArc(double radius, double a0, double a1, double z);

// Piecewise-linear E(s) through the start, middle and end values.
BSplineField threePointModulus(double start, double middle, double end);

// prefix followed by i in three digits at least ("x007").
std::string numbered(const std::string& prefix, std::size_t i);

// A round-capped rod of circular cross-section `diameter` (mm).
Rod circleRod(std::string name, NurbsCurve curve, double diameter, BSplineField modulus);

}  // namespace rodfab::examples::detail
