#include "geometry/nurbs.hpp"
#include "geometry/nurbs_reference.hpp"
#include "geometry/segment.hpp"

#include <algorithm>
#include <limits>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rodfab::geometry {

namespace {

void checkKnotVector(const std::vector<double>& knots, int degree, std::size_t controlCount, const char* what) {
  if (degree < 1 || degree > kMaxDegree)
    throw std::invalid_argument(std::string(what) + ": degree must be in 1.." + std::to_string(kMaxDegree));
  if (controlCount < static_cast<std::size_t>(degree) + 1)
    throw std::invalid_argument(std::string(what) + ": needs at least degree+1 control values");
  if (knots.size() != controlCount + degree + 1)
    throw std::invalid_argument(std::string(what) + ": knot count must be control count + degree + 1");
  for (std::size_t i = 1; i < knots.size(); ++i)
    if (!(knots[i] >= knots[i - 1])) throw std::invalid_argument(std::string(what) + ": knots must be non-decreasing");
  if (!(knots[controlCount] > knots[degree])) throw std::invalid_argument(std::string(what) + ": empty parameter domain");
}

// 8-point Gauss-Legendre nodes and weights on [-1, 1].
constexpr std::array<double, 8> kGaussNodes = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                                               -0.1834346424956498, 0.1834346424956498,  0.5255324099163290,
                                               0.7966664774136267,  0.9602898564975363};
constexpr std::array<double, 8> kGaussWeights = {0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                                                 0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                                                 0.2223810344533745, 0.1012285362903763};

}  // namespace

int findKnotSpan(const std::vector<double>& knots, int degree, int controlCount, double u) {
  const int n = controlCount - 1;
  if (u >= knots[n + 1]) {
    // At (or past) the domain end: use the last non-empty span so the curve is closed at its end.
    int span = n;
    while (span > degree && knots[span] >= knots[n + 1]) --span;
    return span;
  }
  if (u <= knots[degree]) {
    int span = degree;
    while (span < n && knots[span + 1] <= knots[degree]) ++span;
    return span;
  }
  // Largest i in [degree, n] with knots[i] <= u.
  const auto first = knots.begin() + degree;
  const auto last = knots.begin() + n + 1;
  return static_cast<int>(std::upper_bound(first, last, u) - knots.begin()) - 1;
}

namespace {

// Piegl & Tiller, The NURBS Book, algorithm A2.3, for degrees p <= MaxP and orders <= 2. The single
// definition of the basis: the general path instantiates it with MaxP = kMaxDegree and run-time p and
// order; the fixed paths inline it with constant p and order, so the compiler unrolls the loops but
// performs the same floating-point operations in the same order (no -ffast-math, no FMA contraction
// on the baseline x86-64 target), and every result is bit-identical to the general path's.
template <int MaxP>
[[gnu::always_inline]] inline void basisDerivativesUpTo(const double* knots, int p, int span, double u, int order,
                                                        BasisDerivatives& ders) {
  // Every entry of ndu, left and right that is read is written first, so they are not zero-filled.
  std::array<std::array<double, MaxP + 1>, MaxP + 1> ndu;
  std::array<double, MaxP + 1> left, right;
  ndu[0][0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - knots[span + 1 - j];
    right[j] = knots[span + j] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      ndu[j][r] = right[r + 1] + left[j - r];
      const double temp = ndu[r][j - 1] / ndu[j][r];
      ndu[r][j] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    ndu[j][j] = saved;
  }
  for (int j = 0; j <= p; ++j) ders[0][j] = ndu[j][p];
  if (order == 0) return;

  // The coefficient rows are indexed up to the order (j <= k <= order <= 2), not the degree.
  std::array<std::array<double, 3>, 2> a{};
  for (int r = 0; r <= p; ++r) {
    int s1 = 0, s2 = 1;
    a[0][0] = 1.0;
    for (int k = 1; k <= order; ++k) {
      double d = 0.0;
      const int rk = r - k, pk = p - k;
      if (r >= k) {
        a[s2][0] = a[s1][0] / ndu[pk + 1][rk];
        d = a[s2][0] * ndu[rk][pk];
      }
      const int j1 = rk >= -1 ? 1 : -rk;
      const int j2 = (r - 1 <= pk) ? k - 1 : p - r;
      for (int j = j1; j <= j2; ++j) {
        a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j];
        d += a[s2][j] * ndu[rk + j][pk];
      }
      if (r <= pk) {
        a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
        d += a[s2][k] * ndu[r][pk];
      }
      ders[k][r] = d;
      std::swap(s1, s2);
    }
  }
  double factor = p;
  for (int k = 1; k <= order; ++k) {
    for (int j = 0; j <= p; ++j) ders[k][j] *= factor;
    factor *= (p - k);
  }
}

template <int P, int Order>
void basisDerivativesOfDegree(const double* knots, int span, double u, BasisDerivatives& ders) {
  basisDerivativesUpTo<P>(knots, P, span, u, Order, ders);
}

using FixedBasisDerivatives = void (*)(const double*, int, double, BasisDerivatives&);

// The fixed paths by degree (1..3, the rods' and fields' usual degrees) and order (0..2).
constexpr int kFixedMaxDegree = 3;
constexpr std::array<std::array<FixedBasisDerivatives, 3>, kFixedMaxDegree> kFixedBasisDerivatives = {{
    {basisDerivativesOfDegree<1, 0>, basisDerivativesOfDegree<1, 1>, basisDerivativesOfDegree<1, 2>},
    {basisDerivativesOfDegree<2, 0>, basisDerivativesOfDegree<2, 1>, basisDerivativesOfDegree<2, 2>},
    {basisDerivativesOfDegree<3, 0>, basisDerivativesOfDegree<3, 1>, basisDerivativesOfDegree<3, 2>},
}};

}  // namespace

void basisFunctionDerivativesAnyDegree(const std::vector<double>& knots, int p, int span, double u, int order,
                                       BasisDerivatives& ders) {
  basisDerivativesUpTo<kMaxDegree>(knots.data(), p, span, u, order, ders);
}

void basisFunctionDerivatives(const std::vector<double>& knots, int p, int span, double u, int order,
                              BasisDerivatives& ders) {
  if (p >= 1 && p <= kFixedMaxDegree && order >= 0 && order <= 2)
    kFixedBasisDerivatives[p - 1][order](knots.data(), span, u, ders);
  else
    basisFunctionDerivativesAnyDegree(knots, p, span, u, order, ders);
}

NurbsCurve::NurbsCurve(int degree, std::vector<double> knots, std::vector<Vec3> points, std::vector<double> weights)
    : degree_(degree), knots_(std::move(knots)), points_(std::move(points)), weights_(std::move(weights)) {
  checkKnotVector(knots_, degree_, points_.size(), "NurbsCurve");
  if (weights_.empty()) weights_.assign(points_.size(), 1.0);
  if (weights_.size() != points_.size()) throw std::invalid_argument("NurbsCurve: one weight per control point");
  for (double w : weights_)
    if (!(w > 0.0) || !std::isfinite(w)) throw std::invalid_argument("NurbsCurve: weights must be positive");
  rational_ = std::any_of(weights_.begin(), weights_.end(), [&](double w) { return w != weights_.front(); });
}

Vec3 NurbsCurve::point(double u) const {
  Vec3 d[3];
  derivatives(u, 0, d);
  return d[0];
}

void NurbsCurve::derivatives(double u, int order, Vec3* out) const {
  u = std::clamp(u, domainBegin(), domainEnd());
  derivativesInSpan(findKnotSpan(knots_, degree_, static_cast<int>(points_.size()), u), u, order, out);
}

void NurbsCurve::derivativesFromBelow(double u, int order, Vec3* out) const {
  u = std::clamp(u, domainBegin(), domainEnd());
  if (u <= domainBegin()) return derivatives(u, order, out);
  // Largest i in [degree, n) with knots[i] < u: the span whose closure ends at (or contains) u.
  const auto first = knots_.begin() + degree_;
  const auto last = knots_.begin() + static_cast<std::ptrdiff_t>(points_.size());
  const int span = static_cast<int>(std::lower_bound(first, last, u) - knots_.begin()) - 1;
  derivativesInSpan(span, u, order, out);
}

namespace {

// The curve's derivatives from the span's basis (see basisDerivativesUpTo, whose scheme this follows:
// one definition, inlined with constant degree and order on the fixed paths, so the same bits).
template <int MaxP>
[[gnu::always_inline]] inline void curveDerivativesUpTo(const NurbsCurve& curve, int p, int span, double u, int order,
                                                        Vec3* out) {
  BasisDerivatives ders;
  basisDerivativesUpTo<MaxP>(curve.knots().data(), p, span, u, order, ders);
  const std::vector<Vec3>& points = curve.points();
  const std::vector<double>& weights = curve.weights();
  // Homogeneous form: A(u) = sum N_i w_i P_i, w(u) = sum N_i w_i, C = A / w.
  Vec3 a[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  double w[3] = {0.0, 0.0, 0.0};
  for (int j = 0; j <= p; ++j) {
    const int i = span - p + j;
    const double wi = weights[i];
    for (int k = 0; k <= order; ++k) {
      a[k] += (ders[k][j] * wi) * points[i];
      w[k] += ders[k][j] * wi;
    }
  }
  out[0] = a[0] / w[0];
  if (order >= 1) out[1] = (a[1] - w[1] * out[0]) / w[0];
  if (order >= 2) out[2] = (a[2] - 2.0 * w[1] * out[1] - w[2] * out[0]) / w[0];
}

template <int P, int Order>
void curveDerivativesOfDegree(const NurbsCurve& curve, int span, double u, Vec3* out) {
  curveDerivativesUpTo<P>(curve, P, span, u, Order, out);
}

using FixedCurveDerivatives = void (*)(const NurbsCurve&, int, double, Vec3*);

constexpr std::array<std::array<FixedCurveDerivatives, 3>, kFixedMaxDegree> kFixedCurveDerivatives = {{
    {curveDerivativesOfDegree<1, 0>, curveDerivativesOfDegree<1, 1>, curveDerivativesOfDegree<1, 2>},
    {curveDerivativesOfDegree<2, 0>, curveDerivativesOfDegree<2, 1>, curveDerivativesOfDegree<2, 2>},
    {curveDerivativesOfDegree<3, 0>, curveDerivativesOfDegree<3, 1>, curveDerivativesOfDegree<3, 2>},
}};

}  // namespace

void NurbsCurve::derivativesInSpan(int span, double u, int order, Vec3* out) const {
  if (degree_ <= kFixedMaxDegree && order >= 0 && order <= 2)
    kFixedCurveDerivatives[degree_ - 1][order](*this, span, u, out);
  else
    curveDerivativesUpTo<kMaxDegree>(*this, degree_, span, u, order, out);
}

std::vector<double> NurbsCurve::breakpoints() const {
  std::vector<double> result;
  const std::size_t n = points_.size();
  for (std::size_t i = degree_; i < n; ++i)
    if (knots_[i + 1] > knots_[i]) result.push_back(knots_[i]);
  result.push_back(domainEnd());
  return result;
}

double NurbsCurve::arcLength(double u0, double u1) const {
  if (u1 < u0) std::swap(u0, u1);
  u0 = std::max(u0, domainBegin());
  u1 = std::min(u1, domainEnd());
  if (!(u1 > u0)) return 0.0;
  // 8-point Gauss-Legendre on [a, b].
  auto gauss = [&](double a, double b) {
    const double mid = 0.5 * (a + b), half = 0.5 * (b - a);
    double sum = 0.0;
    for (std::size_t g = 0; g < kGaussNodes.size(); ++g) {
      Vec3 d[2];
      derivatives(mid + half * kGaussNodes[g], 1, d);
      sum += half * kGaussWeights[g] * d[1].norm();
    }
    return sum;
  };
  // Each knot span is split into 8 pieces, each integrated with 8 Gauss points: exact enough
  // (better than 1e-10 relative) for the smooth, moderately curved spans of rod designs. The check is
  // the same span in 4 pieces: 8-point Gauss converges as h^16, so where 4 pieces agree with 8 within
  // 1e-9, the 8 pieces' own error is far below it (checking 8 against 16 pieces, as before, cost twice
  // the evaluations for the same sum). Where they disagree (extreme weights race through part of a
  // span) the span is integrated adaptively.
  constexpr int kPiecesPerSpan = 8;
  double length = 0.0;
  const std::vector<double> bp = breakpoints();
  for (std::size_t s = 0; s + 1 < bp.size(); ++s) {
    const double a = std::max(bp[s], u0), b = std::min(bp[s + 1], u1);
    if (!(b > a)) continue;
    const double h = (b - a) / kPiecesPerSpan;
    double span = 0.0, coarse = 0.0;
    for (int piece = 0; piece < kPiecesPerSpan; ++piece) {
      const double mid = a + (piece + 0.5) * h;
      for (std::size_t g = 0; g < kGaussNodes.size(); ++g) {
        Vec3 d[2];
        derivatives(mid + 0.5 * h * kGaussNodes[g], 1, d);
        span += 0.5 * h * kGaussWeights[g] * d[1].norm();
      }
    }
    for (int piece = 0; piece < kPiecesPerSpan; piece += 2) coarse += gauss(a + piece * h, a + (piece + 2) * h);
    if (!(std::abs(span - coarse) > 1e-9 * span)) {
      length += span;
      continue;
    }
    // Bisection while the halves disagree with the whole by more than the interval's share of the
    // span's tolerance (halved at each bisection, so the sum stays within ~1e-10 of the span). A
    // tolerance relative to each interval would chase the kink of |r'| at a near-cusp (r' ~ 0) down to
    // round-off: 2048 intervals a span, 3 minutes for a degree-7 zigzag of 100,000 spans. At most 2048
    // intervals per span (round-off far from the origin would otherwise never settle).
    int budget = 2048;
    auto adaptive = [&](auto&& self, double x, double y, double whole, double tolerance) -> double {
      const double m = 0.5 * (x + y), left = gauss(x, m), right = gauss(m, y);
      if (--budget <= 0 || !(m > x && y > m) || std::abs(left + right - whole) <= tolerance) return left + right;
      return self(self, x, m, left, 0.5 * tolerance) + self(self, m, y, right, 0.5 * tolerance);
    };
    const double pieceTolerance = 1e-10 * std::max(std::abs(span), std::abs(coarse)) / kPiecesPerSpan;
    for (int piece = 0; piece < kPiecesPerSpan; ++piece) {
      const double x = a + piece * h, y = piece + 1 == kPiecesPerSpan ? b : a + (piece + 1) * h;
      length += adaptive(adaptive, x, y, gauss(x, y), pieceTolerance);
    }
  }
  return length;
}

namespace {

// The blossom of span `span`'s polynomial piece (homogeneous control points w P, w) at the arguments
// x[0..p-1]: de Boor's algorithm with the r-th argument at level r. With every argument u it is C(u);
// with p - k arguments a and k arguments b it is the k-th Bezier control point of the piece on [a, b].
Eigen::Vector4d blossom(const NurbsCurve& curve, int span, const double* x) {
  const int p = curve.degree();
  const std::vector<double>& knots = curve.knots();
  std::array<Eigen::Vector4d, kMaxDegree + 1> q;
  for (int j = 0; j <= p; ++j) {
    const int i = span - p + j;
    const double w = curve.weights()[static_cast<std::size_t>(i)];
    q[static_cast<std::size_t>(j)] << w * curve.points()[static_cast<std::size_t>(i)], w;
  }
  for (int r = 1; r <= p; ++r) {
    for (int j = p; j >= r; --j) {
      const int i = span - p + j;
      // knots[i + p + 1 - r] >= knots[span + 1] > knots[span] >= knots[i]: never a zero denominator.
      const double alpha = (x[r - 1] - knots[i]) / (knots[i + p + 1 - r] - knots[i]);
      q[static_cast<std::size_t>(j)] = (1.0 - alpha) * q[static_cast<std::size_t>(j - 1)] + alpha * q[static_cast<std::size_t>(j)];
    }
  }
  return q[static_cast<std::size_t>(p)];
}

}  // namespace

namespace {

// Calls visit(point) for the Bezier control points of `curve` restricted to [a, b] in every non-empty
// knot span meeting it (the span of a alone when a == b): with positive weights the homogeneous ones
// are convex combinations of the curve's (every blossom argument lies in the span), so their weights
// are positive and each piece lies in the convex hull of its points.
template <class Visit>
void forEachBezierPoint(const NurbsCurve& curve, double a, double b, Visit visit) {
  const std::vector<double>& knots = curve.knots();
  a = std::clamp(a, curve.domainBegin(), curve.domainEnd());
  b = std::clamp(b, a, curve.domainEnd());
  const int p = curve.degree(), n = static_cast<int>(curve.points().size());
  for (int span = findKnotSpan(knots, p, n, a); span < n; ++span) {
    if (knots[span + 1] <= knots[span]) continue;
    if (knots[span] > b) break;
    const double x0 = std::max(a, knots[span]), x1 = std::min(b, knots[span + 1]);
    std::array<double, kMaxDegree> x;
    for (int k = 0; k <= p; ++k) {
      for (int r = 0; r < p; ++r) x[static_cast<std::size_t>(r)] = r < p - k ? x0 : x1;
      const Eigen::Vector4d h = blossom(curve, span, x.data());
      visit(Vec3(h.head<3>() / h[3]));
    }
    if (x1 >= b) break;
  }
}

}  // namespace

double NurbsCurve::deviationOn(double a, double b, const Vec3& from, const Vec3& to) const {
  double largest = 0.0;
  forEachBezierPoint(*this, a, b, [&](const Vec3& q) { largest = std::max(largest, distanceToSegment(q, from, to)); });
  return largest;
}

NurbsCurve NurbsCurve::withKnotInserted(double u) const {
  if (!(u > domainBegin() && u < domainEnd())) throw std::invalid_argument("withKnotInserted: u must lie inside the domain");
  const int p = degree_;
  const int n = static_cast<int>(points_.size());
  const int k = findKnotSpan(knots_, p, n, u);
  // New control values Q_i = a_i P_i + (1 - a_i) P_{i-1} for i in (k-p, k], in homogeneous form.
  std::vector<Vec3> points;
  std::vector<double> weights;
  points.reserve(n + 1);
  weights.reserve(n + 1);
  auto w = [&](int i) { return rational_ ? weights_[i] : 1.0; };
  for (int i = 0; i <= n; ++i) {
    if (i <= k - p) {
      points.push_back(points_[i]);
      weights.push_back(w(i));
    } else if (i > k) {
      points.push_back(points_[i - 1]);
      weights.push_back(w(i - 1));
    } else {
      const double a = (u - knots_[i]) / (knots_[i + p] - knots_[i]);
      const double wi = a * w(i) + (1.0 - a) * w(i - 1);
      points.push_back((a * w(i) * points_[i] + (1.0 - a) * w(i - 1) * points_[i - 1]) / wi);
      weights.push_back(wi);
    }
  }
  std::vector<double> knots = knots_;
  knots.insert(knots.begin() + k + 1, u);
  if (!rational_) weights.clear();
  return NurbsCurve(p, std::move(knots), std::move(points), std::move(weights));
}

NurbsCurve NurbsCurve::refined(int insertionsPerSpan) const {
  if (insertionsPerSpan <= 0) return *this;
  const std::vector<double> breaks = breakpoints();
  NurbsCurve curve = *this;
  for (std::size_t s = 0; s + 1 < breaks.size(); ++s)
    for (int i = 1; i <= insertionsPerSpan; ++i)
      curve = curve.withKnotInserted(breaks[s] + (breaks[s + 1] - breaks[s]) * i / (insertionsPerSpan + 1));
  return curve;
}

BSplineField::BSplineField(int degree, std::vector<double> knots, std::vector<double> values)
    : degree_(degree), knots_(std::move(knots)), values_(std::move(values)) {
  checkKnotVector(knots_, degree_, values_.size(), "BSplineField");
}

BSplineField BSplineField::constant(double value, double begin, double end) {
  BSplineField field(1, {begin, begin, end, end}, {value, value});
  field.constant_ = true;
  return field;
}

namespace {

// The field's value (order 0) or first derivative (order 1) at u, a parameter in its domain.
double fieldDerivative(const std::vector<double>& knots, int degree, const std::vector<double>& values, double u, int order) {
  const int span = findKnotSpan(knots, degree, static_cast<int>(values.size()), u);
  BasisDerivatives ders;
  basisFunctionDerivatives(knots, degree, span, u, order, ders);
  double f = 0.0;
  for (int j = 0; j <= degree; ++j) f += ders[order][j] * values[span - degree + j];
  return f;
}

}  // namespace

double BSplineField::value(double u) const {
  return fieldDerivative(knots_, degree_, values_, std::clamp(u, domainBegin(), domainEnd()), 0);
}

std::pair<double, double> BSplineField::valueBoundsOn(double a, double b) const {
  double low = std::numeric_limits<double>::infinity(), high = -low;
  for (std::size_t i = 0; i < values_.size(); ++i)
    if (knots_[i] <= b && knots_[i + degree_ + 1] >= a) {
      low = std::min(low, values_[i]);
      high = std::max(high, values_[i]);
    }
  return {low, high};
}

double BSplineField::derivative(double u) const {
  return fieldDerivative(knots_, degree_, values_, std::clamp(u, domainBegin(), domainEnd()), 1);
}

}  // namespace rodfab::geometry
