#include "geometry/rod.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace rodfab::geometry {

namespace {

double distanceToSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

// Any unit vector not parallel to t: seeds the frame of rods whose section needs none.
Vec3 perpendicularSeed(const Vec3& t) {
  const Vec3 a = t.cwiseAbs();
  if (a.x() <= a.y() && a.x() <= a.z()) return Vec3::UnitX();
  return a.y() <= a.z() ? Vec3::UnitY() : Vec3::UnitZ();
}

// Half-extent of the section along the world axis e, given the frame's d1, d2.
double sectionExtent(const Section& s, const Frame& f, const Vec3& e) {
  const double a = 0.5 * s.width * f.d1.dot(e), b = 0.5 * s.height * f.d2.dot(e);
  if (s.shape == SectionShape::Rectangle) return std::abs(a) + std::abs(b);
  return std::sqrt(a * a + b * b);
}

}  // namespace

Rod::Rod(std::string name, NurbsCurve centerline, Section section, std::optional<Vec3> referenceNormal,
         std::optional<QuaternionSpline> orientation, CapStyle caps, BSplineField modulus)
    : name_(std::move(name)),
      centerline_(std::move(centerline)),
      section_(section),
      referenceNormal_(std::move(referenceNormal)),
      orientation_(std::move(orientation)),
      caps_(caps),
      modulus_(std::move(modulus)) {
  if (referenceNormal_ && orientation_) throw std::invalid_argument("Rod: give either a normal or an orientation");
  if (orientation_) {
    frame_ = RodFrame::fromOrientation(centerline_, *orientation_);
  } else {
    Vec3 d[3];
    centerline_.derivatives(centerline_.domainBegin(), 2, d);
    const Vec3 seed = referenceNormal_ ? *referenceNormal_ : perpendicularSeed(unitTangent(d[1], d[2]));
    frame_ = RodFrame::rotationMinimizing(centerline_, seed);
  }
  length_ = centerline_.arcLength();
  sampleCenterline();
  computeBounds();
}

void Rod::sampleCenterline() {
  // Adaptive polyline: a piece is split while its chord strays from the curve by more than a small
  // fraction of the section or its end tangents turn by more than ~10 degrees. The turning bound
  // keeps (r - p) . r' unimodal on each piece, which the bracketed Newton search relies on.
  const double tolerance = std::max(1e-4, 0.02 * section_.capRadius());
  const double cosTurn = std::cos(10.0 * 3.14159265358979 / 180.0);
  constexpr int kMaxDepth = 14;

  struct Node {
    double u;
    Vec3 p, t;
  };
  auto node = [&](double u) {
    Vec3 d[3];
    centerline_.derivatives(u, 2, d);
    return Node{u, d[0], unitTangent(d[1], d[2])};
  };
  auto deviation = [&](const Node& a, const Node& b) {
    double dev = 0.0;
    for (double f : {0.25, 0.5, 0.75}) dev = std::max(dev, distanceToSegment(centerline_.point(a.u + f * (b.u - a.u)), a.p, b.p));
    return dev;
  };

  std::vector<Node> out;
  std::vector<double> devs;
  auto refine = [&](auto&& self, const Node& a, const Node& b, int depth) -> void {
    const double dev = deviation(a, b);
    if (depth < kMaxDepth && (dev > tolerance || a.t.dot(b.t) < cosTurn)) {
      const Node m = node(0.5 * (a.u + b.u));
      self(self, a, m, depth + 1);
      self(self, m, b, depth + 1);
      return;
    }
    out.push_back(b);
    // Measured at three points; doubled (plus a floor) so it bounds the true deviation of the piece.
    devs.push_back(2.0 * dev + 1e-9);
  };

  const std::vector<double> bp = centerline_.breakpoints();
  out.push_back(node(bp.front()));
  constexpr int kInitialPiecesPerSpan = 4;
  for (std::size_t s = 0; s + 1 < bp.size(); ++s) {
    for (int k = 0; k < kInitialPiecesPerSpan; ++k) {
      const Node a = out.back();
      const Node b = node(bp[s] + (bp[s + 1] - bp[s]) * (k + 1) / kInitialPiecesPerSpan);
      refine(refine, a, b, 0);
    }
  }
  sampleU_.clear();
  samplePoint_.clear();
  for (const Node& n : out) {
    sampleU_.push_back(n.u);
    samplePoint_.push_back(n.p);
  }
  sampleDeviation_ = std::move(devs);
}

ClosestPoint Rod::closestPointInInterval(const Vec3& p, double a, double b) const {
  auto f = [&](double u, Vec3* d) {
    centerline_.derivatives(u, 2, d);
    return (d[0] - p).dot(d[1]);
  };
  auto result = [&](double u) {
    Vec3 d[3];
    centerline_.derivatives(u, 2, d);
    return ClosestPoint{u, d[0], unitTangent(d[1], d[2]), (d[0] - p).norm()};
  };
  Vec3 d[3];
  const double fa = f(a, d);
  if (fa >= 0.0) return result(a);
  const double fb = f(b, d);
  if (fb <= 0.0) return result(b);

  // Safeguarded Newton (Numerical Recipes' rtsafe) on g(u) = (r - p) . r', bracketed by [lo, hi].
  double lo = a, hi = b;
  double u = 0.5 * (a + b);
  double dxOld = b - a, dx = dxOld;
  const double tol = 1e-15 * std::max(1.0, std::abs(b) + std::abs(a));
  for (int it = 0; it < 60; ++it) {
    const double g = f(u, d);
    const double dg = d[1].squaredNorm() + (d[0] - p).dot(d[2]);
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
  return result(std::clamp(u, a, b));
}

ClosestPoint Rod::closestPoint(const Vec3& p) const {
  // Any sample point is on the curve, so the nearest one bounds the answer from above; a piece can
  // hold the closest point only if its segment, widened by its deviation bound, comes that close.
  double upper = std::numeric_limits<double>::infinity();
  for (const Vec3& q : samplePoint_) upper = std::min(upper, (q - p).norm());
  ClosestPoint best;
  best.distance = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < samplePoint_.size(); ++i) {
    if (distanceToSegment(p, samplePoint_[i], samplePoint_[i + 1]) - sampleDeviation_[i] > upper) continue;
    const ClosestPoint c = closestPointInInterval(p, sampleU_[i], sampleU_[i + 1]);
    // Strictly smaller wins: ties keep the lower parameter, so the answer does not depend on order.
    if (c.distance < best.distance) best = c;
  }
  return best;
}

RodHit Rod::classify(const Vec3& p) const { return classify(p, closestPoint(p)); }

RodHit Rod::classify(const Vec3& p, const ClosestPoint& c) const {
  const Vec3 w = p - c.point;
  const double axial = w.dot(c.tangent);
  // Beyond an end plane (the closest point then sits on that end): the cap decides.
  const double planeTolerance = 1e-9 * (1.0 + section_.boundingRadius());
  const bool beyondBegin = c.u <= centerline_.domainBegin() && axial < -planeTolerance;
  const bool beyondEnd = c.u >= centerline_.domainEnd() && axial > planeTolerance;
  RodHit hit;
  hit.u = c.u;
  if (beyondBegin || beyondEnd) {
    if (caps_ == CapStyle::Flat) {
      hit.depth = -std::abs(axial) / section_.capRadius();
      return hit;
    }
    hit.depth = 1.0 - c.distance / section_.capRadius();
    hit.inside = hit.depth >= 0.0;
    return hit;
  }
  const Frame f = frame_.at(c.u, c.point, c.tangent);
  hit.depth = 1.0 - section_.normalizedRadius(w.dot(f.d1), w.dot(f.d2));
  hit.inside = hit.depth >= 0.0;
  return hit;
}

void Rod::computeBounds() {
  bounds_.setEmpty();
  const Vec3 axes[3] = {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  double maxDeviation = 0.0;
  constexpr int kSubsamples = 8;
  for (std::size_t i = 0; i + 1 < sampleU_.size(); ++i) {
    maxDeviation = std::max(maxDeviation, sampleDeviation_[i]);
    for (int k = 0; k <= kSubsamples; ++k) {
      const double u = sampleU_[i] + (sampleU_[i + 1] - sampleU_[i]) * k / kSubsamples;
      Vec3 d[3];
      centerline_.derivatives(u, 2, d);
      const Frame f = frame_.at(u, d[0], unitTangent(d[1], d[2]));
      Vec3 ext;
      for (int a = 0; a < 3; ++a) ext[a] = sectionExtent(section_, f, axes[a]);
      bounds_.extend(Vec3(d[0] - ext));
      bounds_.extend(Vec3(d[0] + ext));
    }
  }
  if (caps_ == CapStyle::Round) {
    const double rc = section_.capRadius();
    for (const double u : {centerline_.domainBegin(), centerline_.domainEnd()}) {
      Vec3 d[3];
      centerline_.derivatives(u, 2, d);
      // The cap is the half-ball on the outer side of the end plane.
      const Vec3 outward = (u == centerline_.domainBegin() ? -1.0 : 1.0) * unitTangent(d[1], d[2]);
      for (int a = 0; a < 3; ++a) {
        const double c = outward[a];
        const double rim = rc * std::sqrt(std::max(0.0, 1.0 - c * c));
        const double hi = c >= 0.0 ? rc : rim, lo = c <= 0.0 ? rc : rim;
        Vec3 top = d[0], bottom = d[0];
        top[a] += hi;
        bottom[a] -= lo;
        bounds_.extend(top);
        bounds_.extend(bottom);
      }
    }
  }
  // Between sub-samples the section can reach slightly further than sampled: the sagitta there is
  // about (1/8)^2 of the piece's deviation; pad by twice that.
  const double pad = maxDeviation / 32.0 + 1e-9;
  bounds_.min().array() -= pad;
  bounds_.max().array() += pad;
}

Box3 RodStructure::bounds() const {
  Box3 box;
  box.setEmpty();
  for (const Rod& r : rods) box.extend(r.bounds());
  return box;
}

DesignSummary summarize(const RodStructure& structure) {
  DesignSummary s;
  s.rodCount = structure.rods.size();
  s.bounds = structure.bounds();
  s.modulusMin = std::numeric_limits<double>::infinity();
  s.modulusMax = -std::numeric_limits<double>::infinity();
  for (const Rod& rod : structure.rods) {
    s.totalLength += rod.length();
    switch (rod.section().shape) {
      case SectionShape::Circle: ++s.circles; break;
      case SectionShape::Ellipse: ++s.ellipses; break;
      case SectionShape::Rectangle: ++s.rectangles; break;
    }
    (rod.caps() == CapStyle::Round ? s.roundCaps : s.flatCaps) += 1;
    const BSplineField& e = rod.modulus();
    constexpr int kSamples = 256;
    for (int k = 0; k <= kSamples; ++k) {
      const double v = e.value(e.domainBegin() + (e.domainEnd() - e.domainBegin()) * k / kSamples);
      s.modulusMin = std::min(s.modulusMin, v);
      s.modulusMax = std::max(s.modulusMax, v);
    }
  }
  return s;
}

}  // namespace rodfab::geometry
