#include "geometry/rod.hpp"
#include "geometry/rod_internal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace rodfab::geometry {

using detail::kFoldSubdivisions;
using detail::safeguardedNewton;

namespace {

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
  length_ = checkedLength(centerline_);
  if (orientation_) {
    frame_ = RodFrame::fromOrientation(centerline_, *orientation_);
  } else {
    Vec3 d[3];
    centerline_.derivatives(centerline_.domainBegin(), 2, d);
    const Vec3 seed = referenceNormal_ ? *referenceNormal_ : perpendicularSeed(unitTangent(d[1], d[2]));
    frame_ = RodFrame::rotationMinimizing(centerline_, seed);
  }
  sampleCenterline();
  computeBounds();
}

double Rod::checkedLength(const NurbsCurve& centerline) {
  const double length = centerline.arcLength();
  if (!std::isfinite(length))
    throw CenterlineError("the centerline's length is not a finite number (weights too extreme for double precision?)");
  Box3 box;
  for (const Vec3& q : centerline.points()) box.extend(q);
  if (!(length > 1e-9 * std::max(1.0, box.diagonal().norm())))
    throw CenterlineError("degenerate centerline: its length is zero (all control points coincide?)");
  return length;
}

void Rod::evaluate(double u, bool fromBelow, Vec3* d) const {
  if (fromBelow) centerline_.derivativesFromBelow(u, 2, d);
  else centerline_.derivatives(u, 2, d);
}

void Rod::findSmoothPieces(const std::vector<double>& bp, std::vector<bool>& isC0) const {
  isC0.assign(bp.size(), false);
  for (std::size_t s = 1; s + 1 < bp.size(); ++s) {
    Vec3 below[3], above[3];
    centerline_.derivativesFromBelow(bp[s], 2, below);
    centerline_.derivatives(bp[s], 2, above);
    isC0[s] = (unitTangentFromBelow(below[1], below[2]) - unitTangent(above[1], above[2])).norm() > kKinkTolerance;
  }
}

namespace {

// The smooth pieces between consecutive C0 samples (`c0Samples`: the index in `sampleU` of every C0
// point and of the last sample), with their parameter ranges and end tangents; evaluate(u, fromBelow,
// d) gives r, r', r'' at u.
template <class Evaluate>
std::vector<SmoothPiece> piecesBetween(const std::vector<double>& sampleU, const std::vector<std::size_t>& c0Samples,
                                       Evaluate evaluate) {
  std::vector<SmoothPiece> pieces;
  std::size_t first = 0;
  for (const std::size_t last : c0Samples) {
    SmoothPiece piece;
    piece.begin = sampleU[first];
    piece.end = sampleU[last];
    piece.firstSample = first;
    piece.lastSample = last;
    piece.endFromBelow = last + 1 < sampleU.size();
    Vec3 d[3];
    evaluate(piece.begin, false, d);
    piece.beginPoint = d[0];
    piece.beginTangent = unitTangent(d[1], d[2]);
    evaluate(piece.end, piece.endFromBelow, d);
    piece.endPoint = d[0];
    piece.endTangent = piece.endFromBelow ? unitTangentFromBelow(d[1], d[2]) : unitTangent(d[1], d[2]);
    pieces.push_back(piece);
    first = last;
  }
  return pieces;
}

}  // namespace

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
  auto node = [&](double u, bool fromBelow) {
    Vec3 d[3];
    evaluate(u, fromBelow, d);
    return Node{u, d[0], fromBelow ? unitTangentFromBelow(d[1], d[2]) : unitTangent(d[1], d[2])};
  };
  auto deviation = [&](const Node& a, const Node& b) {
    double dev = 0.0;
    for (double f : {0.25, 0.5, 0.75}) dev = std::max(dev, distanceToSegment(centerline_.point(a.u + f * (b.u - a.u)), a.p, b.p));
    return dev;
  };

  std::vector<Node> out;
  std::vector<double> devs;
  std::vector<bool> unresolved;
  auto refine = [&](auto&& self, const Node& a, const Node& b, int depth) -> void {
    const double dev = deviation(a, b);
    const bool coarse = dev > tolerance || a.t.dot(b.t) < cosTurn;
    if (depth < kMaxDepth && coarse) {
      const Node m = node(0.5 * (a.u + b.u), false);
      self(self, a, m, depth + 1);
      self(self, m, b, depth + 1);
      return;
    }
    if (out.size() >= kMaxSamplesPerRod)
      throw CenterlineError("rod '" + name_ + "': its centerline needs more than " + std::to_string(kMaxSamplesPerRod) +
                                  " polyline samples to be followed within " + std::to_string(tolerance) +
                                  " mm; split it into shorter rods or use fewer knot spans");
    out.push_back(b);
    // Measured at three points; doubled (plus a floor) so it bounds the true deviation of the piece.
    devs.push_back(2.0 * dev + 1e-9);
    unresolved.push_back(coarse);
  };

  const std::vector<double> bp = centerline_.breakpoints();
  std::vector<bool> isC0;
  findSmoothPieces(bp, isC0);
  out.push_back(node(bp.front(), false));
  std::vector<std::size_t> c0Samples;
  constexpr int kInitialPiecesPerSpan = 4;
  for (std::size_t s = 0; s + 1 < bp.size(); ++s) {
    for (int k = 0; k < kInitialPiecesPerSpan; ++k) {
      // At a C0 point the span before ends with the tangent from below and the next starts from above.
      const Node a = k == 0 && isC0[s] ? node(bp[s], false) : out.back();
      const bool kinkEnd = k + 1 == kInitialPiecesPerSpan && isC0[s + 1];
      const Node b = kinkEnd ? node(bp[s + 1], true) : node(bp[s] + (bp[s + 1] - bp[s]) * (k + 1) / kInitialPiecesPerSpan, false);
      refine(refine, a, b, 0);
    }
    if (isC0[s + 1]) c0Samples.push_back(out.size() - 1);
  }
  sampleU_.clear();
  samplePoint_.clear();
  for (const Node& n : out) {
    sampleU_.push_back(n.u);
    samplePoint_.push_back(n.p);
  }
  sampleDeviation_ = std::move(devs);

  c0Samples.push_back(out.size() - 1);
  pieces_ = piecesBetween(sampleU_, c0Samples, [&](double u, bool fromBelow, Vec3* d) { evaluate(u, fromBelow, d); });
  estimateCurvature(unresolved);
  cacheJets();
  buildSegmentBoxes();
}


void Rod::cacheJets() {
  // The reach of classifySegment (radius + planeTolerance), as first written: it decides which segments
  // cache their fold jets, so it stays this expression (the same number up to the last bit).
  const double reach = section_.boundingRadius() * (1.0 + 1e-9) + 1e-9;
  sampleJet_.clear();
  foldOffset_.assign(sampleDeviation_.size(), kNoFold);
  foldJets_.clear();
  for (const double u : sampleU_) {
    Vec3 d[2];
    centerline_.derivatives(u, 1, d);
    sampleJet_.push_back({d[0], d[1]});
  }
  for (std::size_t i = 0; i < sampleDeviation_.size(); ++i) {
    const double chord = (samplePoint_[i + 1] - samplePoint_[i]).norm();
    if (sampleCurvature_[i] * (reach + 2.0 * sampleDeviation_[i] + chord) < 0.5) continue;
    foldOffset_[i] = foldJets_.size();
    const double a = sampleU_[i], b = sampleU_[i + 1];
    for (int k = 1; k < kFoldSubdivisions; ++k) {
      Vec3 d[2];
      centerline_.derivatives(a + (b - a) * k / kFoldSubdivisions, 1, d);
      foldJets_.push_back({d[0], d[1]});
    }
  }
}

void Rod::estimateCurvature(const std::vector<bool>& unresolved) {
  sampleCurvature_.assign(sampleDeviation_.size(), 0.0);
  for (const SmoothPiece& piece : pieces_) {
    for (std::size_t i = piece.firstSample; i < piece.lastSample; ++i) {
      if (unresolved[i]) {
        sampleCurvature_[i] = kUnresolved;
        continue;
      }
      double largest = 0.0;
      for (const double f : {0.0, 0.25, 0.5, 0.75, 1.0}) {
        Vec3 d[3];
        evaluate(sampleU_[i] + f * (sampleU_[i + 1] - sampleU_[i]), f == 1.0 && i + 1 == piece.lastSample && piece.endFromBelow, d);
        const double speed = d[1].norm();
        // Where the speed vanishes (a clamped end with repeated control points) the others tell.
        if (speed > 1e-14) largest = std::max(largest, d[1].cross(d[2]).norm() / (speed * speed * speed));
      }
      sampleCurvature_[i] = std::isfinite(largest) ? 2.0 * largest : kUnresolved;
    }
  }
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

  // g(u) = (r - p) . r', negative at a and positive at b.
  return result(safeguardedNewton(a, b, [&](double u) {
    const double g = f(u, d);
    return std::pair{g, d[1].squaredNorm() + (d[0] - p).dot(d[2])};
  }));
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

void Rod::computeBounds() {
  bounds_.setEmpty();
  const Vec3 axes[3] = {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  double maxDeviation = 0.0;
  constexpr int kSubsamples = 8;
  for (const SmoothPiece& piece : pieces_) {
    for (std::size_t i = piece.firstSample; i < piece.lastSample; ++i) {
      maxDeviation = std::max(maxDeviation, sampleDeviation_[i]);
      for (int k = 0; k <= kSubsamples; ++k) {
        const double u = sampleU_[i] + (sampleU_[i + 1] - sampleU_[i]) * k / kSubsamples;
        const bool fromBelow = piece.endFromBelow && k == kSubsamples && i + 1 == piece.lastSample;
        Vec3 d[3];
        evaluate(fromBelow ? piece.end : u, fromBelow, d);
        const Vec3 t = fromBelow ? unitTangentFromBelow(d[1], d[2]) : unitTangent(d[1], d[2]);
        const Frame f = frame_.at(fromBelow ? piece.end : u, d[0], t);
        Vec3 ext;
        for (int a = 0; a < 3; ++a) ext[a] = sectionExtent(section_, f, axes[a]);
        bounds_.extend(Vec3(d[0] - ext));
        bounds_.extend(Vec3(d[0] + ext));
      }
      if (!sampleResolved(i)) {
        // The samples may miss what the curve does between them: the segment's points, widened by
        // its deviation and any section, hold it (as far as the deviation holds).
        const double r = sampleDeviation_[i] + section_.boundingRadius();
        bounds_.extend(Vec3(samplePoint_[i].cwiseMin(samplePoint_[i + 1]).array() - r));
        bounds_.extend(Vec3(samplePoint_[i].cwiseMax(samplePoint_[i + 1]).array() + r));
      }
    }
    if (caps_ == CapStyle::Round) {
      const double rc = section_.capRadius();
      for (const bool atEnd : {false, true}) {
        Vec3 d[3];
        evaluate(atEnd ? piece.end : piece.begin, atEnd && piece.endFromBelow, d);
        // The cap is the half-ball on the outer side of the end plane.
        const Vec3 outward = atEnd ? piece.endTangent : Vec3(-piece.beginTangent);
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

void DesignSummary::add(const Rod& rod) {
  ++rodCount;
  totalLength += rod.length();
  bounds.extend(rod.bounds());
  switch (rod.section().shape) {
    case SectionShape::Circle: ++circles; break;
    case SectionShape::Ellipse: ++ellipses; break;
    case SectionShape::Rectangle: ++rectangles; break;
  }
  (rod.caps() == CapStyle::Round ? roundCaps : flatCaps) += 1;
  frameError = std::max(frameError, rod.frame().estimatedError());
  const BSplineField& e = rod.modulus();
  constexpr int kSamples = 256;
  for (int k = 0; k <= kSamples; ++k) {
    const double v = e.value(e.domainBegin() + (e.domainEnd() - e.domainBegin()) * k / kSamples);
    modulusMin = std::min(modulusMin, v);
    modulusMax = std::max(modulusMax, v);
  }
}

void DesignSummary::add(const DesignSummary& later) {
  rodCount += later.rodCount;
  totalLength += later.totalLength;
  bounds.extend(later.bounds);
  modulusMin = std::min(modulusMin, later.modulusMin);
  modulusMax = std::max(modulusMax, later.modulusMax);
  circles += later.circles, ellipses += later.ellipses, rectangles += later.rectangles;
  roundCaps += later.roundCaps, flatCaps += later.flatCaps;
  frameError = std::max(frameError, later.frameError);
}

DesignSummary summarize(const RodStructure& structure) {
  DesignSummary s;
  for (const Rod& rod : structure.rods) s.add(rod);
  return s;
}

}  // namespace rodfab::geometry
