// NURBS curves and B-spline scalar fields: evaluation with derivatives, allocation-free.
#pragma once

#include <Eigen/Core>

#include <array>
#include <utility>
#include <vector>

namespace rodfab::geometry {

using Vec3 = Eigen::Vector3d;

// Highest polynomial degree supported. Evaluation keeps its work arrays on the stack, so the bound
// is fixed; Cosserat solvers and CAD curves stay well below it.
constexpr int kMaxDegree = 7;

// The span index i with knots[i] <= u < knots[i+1], clamped to the valid domain
// [knots[degree], knots[n]] where n is the number of control points.
int findKnotSpan(const std::vector<double>& knots, int degree, int controlCount, double u);

// Non-zero basis functions N_{span-degree..span} and their derivatives up to `order` (<= 2) at u.
// ders[k][j] is the k-th derivative of N_{span-degree+j}.
using BasisDerivatives = std::array<std::array<double, kMaxDegree + 1>, 3>;
void basisFunctionDerivatives(const std::vector<double>& knots, int degree, int span, double u, int order,
                              BasisDerivatives& ders);

// A (possibly rational) curve in R^3. The parameter domain is [knots[degree], knots[n]].
class NurbsCurve {
public:
  NurbsCurve() = default;
  // Throws std::invalid_argument when counts or values are inconsistent; readers validate first
  // and report user-facing errors, so this is the programming-error backstop.
  NurbsCurve(int degree, std::vector<double> knots, std::vector<Vec3> points, std::vector<double> weights = {});

  int degree() const { return degree_; }
  const std::vector<double>& knots() const { return knots_; }
  const std::vector<Vec3>& points() const { return points_; }
  const std::vector<double>& weights() const { return weights_; }
  bool isRational() const { return rational_; }
  double domainBegin() const { return knots_[degree_]; }
  double domainEnd() const { return knots_[points_.size()]; }

  Vec3 point(double u) const;
  // out[0] = C(u), out[1] = C'(u), out[2] = C''(u) for k <= order (order <= 2). At a knot the
  // derivatives are those of the span that starts there (the limit from above), except at the domain end.
  void derivatives(double u, int order, Vec3* out) const;
  // The same from the span that ends at u (the limit from below); at the domain begin, from above.
  // Differs from derivatives() only at knots where the curve is not C^order, e.g. at a kink.
  void derivativesFromBelow(double u, int order, Vec3* out) const;

  // Arc length over the whole domain or [u0, u1], by Gauss-Legendre quadrature on each knot span.
  double arcLength() const { return arcLength(domainBegin(), domainEnd()); }
  double arcLength(double u0, double u1) const;

  // Start of every non-empty knot span, plus the domain end.
  std::vector<double> breakpoints() const;

  // How far C(u) for u in [a, b] (a <= b, inside the domain) may lie from the segment [from, to]: the
  // largest distance from it of the Bezier control points of the curve restricted to [a, b] in each
  // knot span it meets (blossoms, in homogeneous form). By the convex-hull property (the weights are
  // positive) and the convexity of the distance to a segment, every C(u) there lies within it, up to
  // the round-off of the two computations, a few ulps of (largest weight / smallest weight) times the
  // largest control coordinate.
  double deviationOn(double a, double b, const Vec3& from, const Vec3& to) const;

  // The same curve with `insertionsPerSpan` knots inserted evenly into every non-empty span
  // (Boehm's knot insertion in homogeneous coordinates): h-refinement for the rod solver.
  NurbsCurve refined(int insertionsPerSpan) const;
  // The same curve with the knot u inserted once (u strictly inside the domain).
  NurbsCurve withKnotInserted(double u) const;

private:
  void derivativesInSpan(int span, double u, int order, Vec3* out) const;

  int degree_ = 0;
  std::vector<double> knots_;
  std::vector<Vec3> points_;
  std::vector<double> weights_;
  bool rational_ = false;
};

// A scalar B-spline field f(u) (for example Young's modulus E(s) along a rod).
class BSplineField {
public:
  BSplineField() = default;
  BSplineField(int degree, std::vector<double> knots, std::vector<double> values);
  // A field equal to `value` everywhere on [begin, end].
  static BSplineField constant(double value, double begin, double end);

  int degree() const { return degree_; }
  const std::vector<double>& knots() const { return knots_; }
  const std::vector<double>& values() const { return values_; }
  bool isConstant() const { return constant_; }
  double domainBegin() const { return knots_[degree_]; }
  double domainEnd() const { return knots_[values_.size()]; }

  double value(double u) const;
  double derivative(double u) const;
  // Bounds of the field on [a, b] (a <= b, inside the domain): the least and greatest value of the
  // control values whose basis functions do not vanish there (the convex-hull property), so every
  // value(u) for u in [a, b] lies within them.
  std::pair<double, double> valueBoundsOn(double a, double b) const;

private:
  int degree_ = 0;
  std::vector<double> knots_;
  std::vector<double> values_;
  bool constant_ = false;
};

}  // namespace rodfab::geometry
