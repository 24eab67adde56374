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

}  // namespace

RodFrame RodFrame::rotationMinimizing(const NurbsCurve& curve, const Vec3& referenceNormal) {
  RodFrame frame;
  frame.kind_ = Kind::RotationMinimizing;
  // 64 samples per knot span keep the discrete RMF within ~1e-8 rad of the exact one for the
  // curvatures of printable rods; the step error of double reflection is fourth order. Curves of
  // more than 1024 spans (short ones) get fewer, down to 4, so memory stays a small multiple of the
  // design file's size.
  const std::vector<double> bp = curve.breakpoints();
  const std::size_t spans = bp.size() - 1;
  const int kSamplesPerSpan = static_cast<int>(std::clamp<std::size_t>(kMaxFrameSamples / spans, 4, 64));
  for (std::size_t s = 0; s + 1 < bp.size(); ++s)
    for (int k = 0; k < kSamplesPerSpan; ++k)
      frame.sampleU_.push_back(bp[s] + (bp[s + 1] - bp[s]) * k / kSamplesPerSpan);
  frame.sampleU_.push_back(bp.back());

  for (double u : frame.sampleU_) {
    Vec3 d[3];
    curve.derivatives(u, 2, d);
    frame.samplePoint_.push_back(d[0]);
    frame.sampleTangent_.push_back(unitTangent(d[1], d[2]));
  }
  const Vec3& t0 = frame.sampleTangent_.front();
  if (!referenceNormal.allFinite() || !(referenceNormal.cwiseAbs().maxCoeff() > 0.0))
    throw std::invalid_argument("RodFrame: reference normal must be non-zero and finite");
  // Scaled by a power of two (exact) to a largest component in [1, 2): no overflow for 1e300.
  const Vec3 n = scaledToUnitOrder(referenceNormal);
  Vec3 d1 = n - n.dot(t0) * t0;
  if (!(d1.norm() > 1e-9 * n.norm()))
    throw std::invalid_argument("RodFrame: reference normal is parallel to the centerline tangent");
  d1.normalize();
  frame.sampleD1_.push_back(d1);
  for (std::size_t i = 1; i < frame.sampleU_.size(); ++i)
    frame.sampleD1_.push_back(doubleReflect(frame.samplePoint_[i - 1], frame.sampleTangent_[i - 1],
                                            frame.sampleD1_[i - 1], frame.samplePoint_[i], frame.sampleTangent_[i]));
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
