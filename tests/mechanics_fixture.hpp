// Shared by the mechanics tests (tests/test_mechanics*.cpp): curves, rods, places on them, supports
// and loads added to a design, a loaded cantilever, discretizations and solves.
#pragma once

#include "geometry/geometry.hpp"
#include "mechanics/mechanics.hpp"

#include <cmath>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

namespace rodfab::test {

using geometry::Vec3;

// Clamped uniform knot vector for `count` control values of degree p on [0, 1].
inline std::vector<double> uniformKnots(int p, int count) {
  std::vector<double> k(p + 1, 0.0);
  const int spans = count - p;
  for (int i = 1; i < spans; ++i) k.push_back(static_cast<double>(i) / spans);
  k.insert(k.end(), p + 1, 1.0);
  return k;
}

// Straight rod from a to b, degree p, `count` control points at the Greville abscissae (so the
// parameter on [0, 1] is proportional to arc length).
inline geometry::NurbsCurve straight(const Vec3& a, const Vec3& b, int p = 3, int count = 4) {
  const auto knots = uniformKnots(p, count);
  std::vector<Vec3> pts;
  for (int j = 0; j < count; ++j) {
    double t = 0;
    for (int i = 1; i <= p; ++i) t += knots[j + i];
    pts.push_back(a + (b - a) * (t / p));
  }
  return geometry::NurbsCurve(p, knots, pts);
}

// Circular arc of radius R about c in the xy-plane from angle a0 to a1 (< pi / 2 per call), exact
// rational quadratic.
inline geometry::NurbsCurve arc(double R, double a0, double a1, const Vec3& c = Vec3::Zero()) {
  const double am = 0.5 * (a0 + a1), w = std::cos(0.5 * (a1 - a0));
  return geometry::NurbsCurve(2, {0, 0, 0, 1, 1, 1},
                              {c + R * Vec3(std::cos(a0), std::sin(a0), 0), c + R / w * Vec3(std::cos(am), std::sin(am), 0),
                               c + R * Vec3(std::cos(a1), std::sin(a1), 0)},
                              {1.0, w, 1.0});
}

// A round-capped rod of constant modulus E (MPa).
inline geometry::Rod rod(const std::string& name, geometry::NurbsCurve curve, const geometry::Section& section, double E,
                         std::optional<Vec3> normal = std::nullopt) {
  const double a = curve.domainBegin(), b = curve.domainEnd();
  return geometry::Rod(name, std::move(curve), section, normal, std::nullopt, geometry::CapStyle::Round,
                       geometry::BSplineField::constant(E, a, b));
}

// Places: a rod's end, a rod's point at parameter u, whatever lies at a point.
inline mechanics::RodEndRef at(const std::string& rod, mechanics::RodEnd end, const std::string& path = "test") {
  mechanics::RodEndRef r;
  r.rod = rod, r.end = end, r.path = path;
  return r;
}
inline mechanics::RodEndRef atParameter(const std::string& rod, double u, const std::string& path = "test") {
  mechanics::RodEndRef r;
  r.rod = rod, r.parameter = u, r.path = path;
  return r;
}
inline mechanics::RodEndRef atPoint(const Vec3& p, const std::string& path = "test") {
  mechanics::RodEndRef r;
  r.point = p, r.path = path;
  return r;
}

inline void clamp(mechanics::Design& s, const mechanics::RodEndRef& where) {
  mechanics::Support c;
  c.at = where;
  s.mechanics.supports.push_back(c);
}

inline void load(mechanics::Design& s, const mechanics::RodEndRef& where, const Vec3& force) {
  mechanics::PointLoad l;
  l.at = where;
  l.force = force;
  s.mechanics.loads.push_back(l);
}

// ---- Cantilevers, discretizations, solves

inline constexpr double kPi = std::numbers::pi;

// One rod "beam" clamped at its start and loaded at its end (nu = 0.3).
inline mechanics::Design cantilever(geometry::NurbsCurve curve, const geometry::Section& section, double E, const Vec3& force,
                                    const Vec3& moment, std::optional<Vec3> normal = std::nullopt) {
  mechanics::Design s;
  s.source = "cantilever";
  s.rods.push_back(rod("beam", std::move(curve), section, E, normal));
  s.mechanics.present = true;
  s.mechanics.poissonRatio = 0.3;
  clamp(s, at("beam", mechanics::RodEnd::Start));
  mechanics::PointLoad tipLoad;
  tipLoad.at = at("beam", mechanics::RodEnd::End);
  tipLoad.force = force;
  tipLoad.moment = moment;
  s.mechanics.loads.push_back(tipLoad);
  return s;
}

// Rod `rodIndex`'s centerline point at u = 1 (the end of a rod drawn on [0, 1]) in state x.
inline Vec3 tip(const mechanics::StaticProblem& problem, const Eigen::VectorXd& x, std::size_t rodIndex = 0) {
  return problem.position(x, rodIndex, 1.0);
}

// The design's own basis, `refine` knots inserted per span.
inline mechanics::Discretization designBasis(int refine) {
  mechanics::Discretization d;
  d.degree = 0;
  d.refine = refine;
  return d;
}

// Every rod rebuilt at `degree` with `spans` uniform spans.
inline mechanics::Discretization rebuilt(int degree, int spans) {
  mechanics::Discretization d;
  d.degree = degree;
  d.spans = spans;
  return d;
}

// The state at load 1, reached in `steps` load steps.
inline Eigen::VectorXd solved(const mechanics::StaticProblem& problem, int steps) {
  mechanics::SolverOptions options;
  options.loadSteps = steps;
  return mechanics::solve(problem, options, steps).state;
}

}  // namespace rodfab::test
