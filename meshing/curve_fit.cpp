// Global cubic interpolation (Piegl & Tiller, The NURBS Book, 2nd ed., algorithm A9.1).
#include "meshing/mesh.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace rodfab::meshing {

geometry::NurbsCurve interpolateCubic(const std::vector<Vec3>& points) {
  constexpr int p = 3;
  const int n = static_cast<int>(points.size()) - 1;
  if (n < p) throw std::invalid_argument("interpolateCubic: needs at least 4 points");
  // Chord-length parameters on [0, 1].
  std::vector<double> ubar(n + 1, 0.0);
  for (int k = 1; k <= n; ++k) ubar[k] = ubar[k - 1] + (points[k] - points[k - 1]).norm();
  // Checked before scaling: comparing a scaled parameter with the next unscaled one refused every
  // curve shorter than 1 mm (the bunny's rods from 2,174 faces on).
  for (int k = 1; k <= n; ++k)
    if (!(ubar[k] > ubar[k - 1])) throw std::invalid_argument("interpolateCubic: two consecutive points coincide");
  const double total = ubar[n];
  for (int k = 1; k <= n; ++k) ubar[k] /= total;
  ubar[n] = 1.0;
  for (int k = 1; k <= n; ++k)
    if (!(ubar[k] > ubar[k - 1])) throw std::invalid_argument("interpolateCubic: two consecutive points too close to tell apart");
  // Knots by averaging p consecutive parameters: every span holds a data parameter, so A is regular.
  std::vector<double> knots(n + p + 2, 0.0);
  for (int j = 1; j <= n - p; ++j) {
    double sum = 0;
    for (int i = j; i < j + p; ++i) sum += ubar[i];
    knots[j + p] = sum / p;
  }
  for (int j = n + 1; j <= n + p + 1; ++j) knots[j] = 1.0;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n + 1, n + 1);
  geometry::BasisDerivatives basis;
  for (int k = 0; k <= n; ++k) {
    const int span = geometry::findKnotSpan(knots, p, n + 1, ubar[k]);
    geometry::basisFunctionDerivatives(knots, p, span, ubar[k], 0, basis);
    for (int j = 0; j <= p; ++j) a(k, span - p + j) = basis[0][j];
  }
  Eigen::MatrixXd q(n + 1, 3);
  for (int k = 0; k <= n; ++k) q.row(k) = points[k].transpose();
  const Eigen::MatrixXd control = a.partialPivLu().solve(q);
  std::vector<Vec3> controlPoints(n + 1);
  for (int k = 0; k <= n; ++k) controlPoints[k] = control.row(k).transpose();
  // The clamped ends interpolate exactly; set them so rods sharing a node share its bits.
  controlPoints.front() = points.front();
  controlPoints.back() = points.back();
  return geometry::NurbsCurve(p, std::move(knots), std::move(controlPoints));
}

double smallestBendRadius(const geometry::NurbsCurve& curve, int pointsPerSpan) {
  const std::vector<double> breaks = curve.breakpoints();
  double largestCurvature = 0;
  for (std::size_t s = 0; s + 1 < breaks.size(); ++s)
    for (int i = 0; i <= pointsPerSpan; ++i) {
      Vec3 d[3];
      const double u = breaks[s] + (breaks[s + 1] - breaks[s]) * i / pointsPerSpan;
      if (i == pointsPerSpan && s + 2 < breaks.size()) curve.derivativesFromBelow(u, 2, d);  // the span's own end
      else curve.derivatives(u, 2, d);
      const double speed = d[1].norm();
      if (speed > 0) largestCurvature = std::max(largestCurvature, d[1].cross(d[2]).norm() / (speed * speed * speed));
    }
  return largestCurvature > 0 ? 1.0 / largestCurvature : std::numeric_limits<double>::infinity();
}

}  // namespace rodfab::meshing
