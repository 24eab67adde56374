#include "geometry/frame.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace rodfab::geometry {

Vec3 unitTangent(const Vec3& d1, const Vec3& d2) {
  const double n = d1.norm();
  if (n > 1e-14) return d1 / n;
  const double n2 = d2.norm();
  return n2 > 0.0 ? Vec3(d2 / n2) : Vec3::UnitZ();
}

Vec3 unitTangentFromBelow(const Vec3& d1, const Vec3& d2) {
  // Where r' vanishes the curve arrives along -r'' (r'(u - h) ~ -h r''(u)).
  const double n = d1.norm();
  if (n > 1e-14) return d1 / n;
  const double n2 = d2.norm();
  return n2 > 0.0 ? Vec3(-d2 / n2) : Vec3::UnitZ();
}

double stableNorm(const Eigen::Ref<const Eigen::VectorXd>& v) {
  // Scaled by the largest component first, so 1e200 and 1e-200 neither overflow nor underflow.
  const double scale = v.cwiseAbs().maxCoeff();
  if (!(scale > 0.0) || !std::isfinite(scale)) return scale;
  return scale * (v / scale).norm();
}

Vec3 scaledToUnitOrder(const Vec3& v) {
  const double largest = v.cwiseAbs().maxCoeff();
  if (!(largest > 0.0) || !std::isfinite(largest)) return v;
  // Component by component: 2^1063 (for a largest component of 1e-320) is no double, but scalbn
  // scales a denormal exactly.
  const int exponent = -std::ilogb(largest);
  return v.unaryExpr([exponent](double x) { return std::scalbn(x, exponent); });
}

QuaternionSpline::QuaternionSpline(int degree, std::vector<double> knots, std::vector<Eigen::Vector4d> quaternions)
    : degree_(degree), knots_(std::move(knots)), quaternions_(std::move(quaternions)) {
  if (degree_ < 1 || degree_ > kMaxDegree) throw std::invalid_argument("QuaternionSpline: bad degree");
  if (quaternions_.size() < static_cast<std::size_t>(degree_) + 1 ||
      knots_.size() != quaternions_.size() + degree_ + 1)
    throw std::invalid_argument("QuaternionSpline: knot count must be quaternion count + degree + 1");
  double largest = 0.0;
  for (const Eigen::Vector4d& q : quaternions_) {
    if (!q.allFinite() || !(q.cwiseAbs().maxCoeff() > 0.0))
      throw std::invalid_argument("QuaternionSpline: quaternions must be non-zero and finite");
    largest = std::max(largest, q.cwiseAbs().maxCoeff());
  }
  const double scale = std::ldexp(1.0, -std::ilogb(largest));
  for (const Eigen::Vector4d& q : quaternions_) scaledQuaternions_.push_back(q * scale);
}

Eigen::Quaterniond QuaternionSpline::rotation(double u) const {
  u = std::clamp(u, domainBegin(), domainEnd());
  const int span = findKnotSpan(knots_, degree_, static_cast<int>(quaternions_.size()), u);
  BasisDerivatives ders;
  basisFunctionDerivatives(knots_, degree_, span, u, 0, ders);
  // The control quaternions are stored scaled by one power of two (exact), so components like 1e160
  // neither overflow the norm (which turned them into the identity) nor change the blend's direction.
  Eigen::Vector4d q = Eigen::Vector4d::Zero();
  for (int j = 0; j <= degree_; ++j) q += ders[0][j] * scaledQuaternions_[span - degree_ + j];
  const double n = q.norm();
  if (!(n > 0.0) || !std::isfinite(n)) return Eigen::Quaterniond::Identity();
  q /= n;
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
}

namespace {

// One double-reflection step: carries d1 from (x0, t0) to (x1, t1) without rotation about the tangent.
Vec3 doubleReflect(const Vec3& x0, const Vec3& t0, const Vec3& d1, const Vec3& x1, const Vec3& t1) {
  const Vec3 v1 = x1 - x0;
  const double c1 = v1.squaredNorm();
  Vec3 rL = d1, tL = t0;
  if (c1 > 1e-28) {
    rL = d1 - (2.0 / c1) * v1.dot(d1) * v1;
    tL = t0 - (2.0 / c1) * v1.dot(t0) * v1;
  }
  const Vec3 v2 = t1 - tL;
  const double c2 = v2.squaredNorm();
  Vec3 r = c2 > 1e-28 ? Vec3(rL - (2.0 / c2) * v2.dot(rL) * v2) : rL;
  // Remove round-off drift so d1 stays exactly in the cross-section plane.
  r -= r.dot(t1) * t1;
  return r.normalized();
}

// A curve's points and unit tangents at `perSpan` evenly spaced parameters a knot span and the end.
struct CurveSamples {
  std::vector<double> u;
  std::vector<Vec3> point, tangent;
};

double sampleParameter(const std::vector<double>& bp, std::size_t span, int k, int perSpan) {
  return bp[span] + (bp[span + 1] - bp[span]) * k / perSpan;
}

void addSample(const NurbsCurve& curve, double u, CurveSamples& out) {
  Vec3 d[3];
  curve.derivatives(u, 2, d);
  out.u.push_back(u);
  out.point.push_back(d[0]);
  out.tangent.push_back(unitTangent(d[1], d[2]));
}

CurveSamples sampleSpans(const NurbsCurve& curve, const std::vector<double>& bp, int perSpan) {
  CurveSamples out;
  const std::size_t count = (bp.size() - 1) * std::size_t(perSpan) + 1;
  out.u.reserve(count), out.point.reserve(count), out.tangent.reserve(count);
  for (std::size_t s = 0; s + 1 < bp.size(); ++s)
    for (int k = 0; k < perSpan; ++k) addSample(curve, sampleParameter(bp, s, k, perSpan), out);
  addSample(curve, bp.back(), out);
  return out;
}

// The samples at twice as many a span: `coarse`'s own (their parameters are the same doubles: k / m
// and 2k / 2m give the same quotient) with the curve evaluated between them only.
CurveSamples refineSamples(const NurbsCurve& curve, const std::vector<double>& bp, const CurveSamples& coarse,
                           int coarsePerSpan) {
  CurveSamples out;
  const std::size_t count = 2 * coarse.u.size() - 1;
  out.u.reserve(count), out.point.reserve(count), out.tangent.reserve(count);
  const int finePerSpan = 2 * coarsePerSpan;
  for (std::size_t i = 0; i + 1 < coarse.u.size(); ++i) {
    out.u.push_back(coarse.u[i]), out.point.push_back(coarse.point[i]), out.tangent.push_back(coarse.tangent[i]);
    const std::size_t span = i / std::size_t(coarsePerSpan);
    const int k = int(i % std::size_t(coarsePerSpan));
    addSample(curve, sampleParameter(bp, span, 2 * k + 1, finePerSpan), out);
  }
  out.u.push_back(coarse.u.back()), out.point.push_back(coarse.point.back()), out.tangent.push_back(coarse.tangent.back());
  return out;
}

// d1 carried from the first sample along all of them by double reflection.
std::vector<Vec3> propagate(const CurveSamples& s, const Vec3& d1) {
  std::vector<Vec3> out;
  out.reserve(s.u.size());
  out.push_back(d1);
  for (std::size_t i = 1; i < s.u.size(); ++i)
    out.push_back(doubleReflect(s.point[i - 1], s.tangent[i - 1], out[i - 1], s.point[i], s.tangent[i]));
  return out;
}

// The largest angle (rad) between the coarse frames and the fine ones at the coarse samples (the
// fine samples' even indices).
double largestDifference(const std::vector<Vec3>& coarse, const std::vector<Vec3>& fine) {
  double largest = 0.0;
  for (std::size_t i = 0; i < coarse.size(); ++i) {
    const double chord = (coarse[i] - fine[2 * i]).norm();
    largest = std::max(largest, 2.0 * std::asin(std::min(1.0, 0.5 * chord)));
  }
  return largest;
}

// d1 at the first sample: the reference normal projected onto the first cross-section plane.
Vec3 seedNormal(const Vec3& referenceNormal, const Vec3& t0) {
  if (!referenceNormal.allFinite() || !(referenceNormal.cwiseAbs().maxCoeff() > 0.0))
    throw std::invalid_argument("RodFrame: reference normal must be non-zero and finite");
  // Scaled by a power of two (exact) to a largest component in [1, 2): no overflow for 1e300.
  const Vec3 n = scaledToUnitOrder(referenceNormal);
  Vec3 d1 = n - n.dot(t0) * t0;
  if (!(d1.norm() > 1e-9 * n.norm()))
    throw std::invalid_argument("RodFrame: reference normal is parallel to the centerline tangent");
  return d1.normalized();
}

}  // namespace

RodFrame RodFrame::rotationMinimizing(const NurbsCurve& curve, const Vec3& referenceNormal) {
  // Double reflection's error is fourth order in the step, so the frames at m samples a span differ
  // from those at 2m by about 15/16 of the former's error: the fewest samples whose frames agree with
  // twice as many within kFrameTolerance are kept (a short, gently bent rod needs 4 a span, a coil of
  // 16 control points a turn 64). Curves of many spans stop doubling earlier (kMaxFrameSamples; at
  // least 4 a span), so memory stays a small multiple of the design file's size.
  const std::vector<double> bp = curve.breakpoints();
  const std::size_t spans = bp.size() - 1;
  const int mostPerSpan = static_cast<int>(std::clamp<std::size_t>(kMaxFrameSamples / spans, 4, kMaxSamplesPerSpan));
  int perSpan = 4;
  CurveSamples samples = sampleSpans(curve, bp, perSpan);
  const Vec3 d1 = seedNormal(referenceNormal, samples.tangent.front());
  std::vector<Vec3> frames = propagate(samples, d1);
  double estimatedError = 0.0;
  while (true) {
    CurveSamples fine = refineSamples(curve, bp, samples, perSpan);
    std::vector<Vec3> fineFrames = propagate(fine, d1);
    const double difference = largestDifference(frames, fineFrames);
    if (difference <= kFrameTolerance || 2 * perSpan > mostPerSpan) {  // the coarse frames kept
      estimatedError = difference * 16.0 / 15.0;
      break;
    }
    samples = std::move(fine), frames = std::move(fineFrames), perSpan *= 2;
    if (2 * perSpan > mostPerSpan) {  // the most samples allowed: an error about a 16th of the coarser one's
      estimatedError = difference / 15.0;
      break;
    }
  }
  RodFrame frame;
  frame.kind_ = Kind::RotationMinimizing;
  frame.sampleU_ = std::move(samples.u);
  frame.samplePoint_ = std::move(samples.point);
  frame.sampleTangent_ = std::move(samples.tangent);
  frame.sampleD1_ = std::move(frames);
  frame.estimatedError_ = estimatedError;
  return frame;
}

RodFrame RodFrame::fromOrientation(const NurbsCurve&, QuaternionSpline orientation) {
  RodFrame frame;
  frame.kind_ = Kind::Orientation;
  frame.orientation_ = std::move(orientation);
  return frame;
}

Frame RodFrame::at(double u, const Vec3& point, const Vec3& t) const {
  Vec3 d1;
  if (kind_ == Kind::RotationMinimizing) {
    const auto it = std::upper_bound(sampleU_.begin(), sampleU_.end(), u);
    std::size_t i = it == sampleU_.begin() ? 0 : static_cast<std::size_t>(it - sampleU_.begin()) - 1;
    // At a kink the sample holds the tangent from above; a frame asked with the tangent from below
    // (the end of the piece before the kink) continues from the sample before, like its neighbours.
    if (i > 0 && sampleU_[i] == u && (t - sampleTangent_[i]).squaredNorm() > 1e-18) --i;
    d1 = doubleReflect(samplePoint_[i], sampleTangent_[i], sampleD1_[i], point, t);
  } else {
    const Eigen::Matrix3d r = orientation_.rotation(u).toRotationMatrix();
    d1 = r.col(0) - r.col(0).dot(t) * t;
    if (d1.squaredNorm() < 1e-20) {
      // The solver's d1 is along the tangent (extreme shear): fall back to its d2.
      const Vec3 d2 = r.col(1) - r.col(1).dot(t) * t;
      d1 = d2.cross(t);
    }
    d1.normalize();
  }
  return {d1, t.cross(d1), t};
}

Frame RodFrame::at(const NurbsCurve& curve, double u) const {
  Vec3 d[3];
  curve.derivatives(u, 2, d);
  return at(u, d[0], unitTangent(d[1], d[2]));
}

}  // namespace rodfab::geometry
