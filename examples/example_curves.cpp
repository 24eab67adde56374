#include "examples/example_curves.hpp"

#include <cmath>
#include <cstdio>

namespace rodfab::examples::detail {
NurbsCurve straight(const Vec3& a, const Vec3& b) { return NurbsCurve(1, {0, 0, 1, 1}, {a, b}); }

NurbsCurve cubicThrough(const std::function<Vec3(double)>& q) {
  return NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1, 1}, bezierThrough<Vec3>({q(0.0), q(1.0 / 3.0), q(2.0 / 3.0), q(1.0)}));
}

geometry::QuaternionSpline quaternionsThrough(const std::function<Eigen::Vector4d(double)>& q) {
  std::array<Eigen::Vector4d, 4> s = {q(0.0), q(1.0 / 3.0), q(2.0 / 3.0), q(1.0)};
  for (int i = 1; i < 4; ++i)
    if (s[i].dot(s[i - 1]) < 0.0) s[i] = -s[i];
  return geometry::QuaternionSpline(3, {0, 0, 0, 0, 1, 1, 1, 1}, bezierThrough(s));
}

NurbsCurve ringArc(double radius, double a0, double a1, double z) {
  const double half = 0.5 * (a1 - a0), mid = 0.5 * (a0 + a1);
  const double w = std::cos(half);
  const Vec3 p0(radius * std::cos(a0), radius * std::sin(a0), z);
  const Vec3 p1(radius / w * std::cos(mid), radius / w * std::sin(mid), z);
  const Vec3 p2(radius * std::cos(a1), radius * std::sin(a1), z);
  return NurbsCurve(2, {0, 0, 0, 1, 1, 1}, {p0, p1, p2}, {1, w, 1});
}

BSplineField threePointModulus(double start, double middle, double end) {
  return BSplineField(1, {0, 0, 0.5, 1, 1}, {start, middle, end});
}

std::string numbered(const std::string& prefix, std::size_t i) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%03zu", i);
  return prefix + buf;
}

Rod circleRod(std::string name, NurbsCurve curve, double diameter, BSplineField modulus) {
  return Rod(std::move(name), std::move(curve), Section::circle(diameter), std::nullopt, std::nullopt,
             CapStyle::Round, std::move(modulus));
}

}  // namespace rodfab::examples::detail
