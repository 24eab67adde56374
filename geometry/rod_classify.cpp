// Rod::classify, the inside test: the sections through a point (the zeros of (r - p) . r' on the sample
// segments whose boxes hold it), the end planes and caps, and the segment boxes it walks.
#include "geometry/rod.hpp"
#include "geometry/rod_internal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rodfab::geometry {

using detail::kFoldSubdivisions;
using detail::safeguardedNewton;

double Rod::solveCrossing(const Vec3& p, double a, double b, double sign) const {
  // A zero of sign * g(u), g = (r - p) . r', negative at a and positive at b; sign = -1 finds the zeros
  // where g falls (farthest points, only on tight bends).
  auto f = [&](double u, Vec3* d) {
    centerline_.derivatives(u, 2, d);
    return sign * (d[0] - p).dot(d[1]);
  };
  Vec3 d[3];
  return safeguardedNewton(a, b, [&](double u) {
    const double g = f(u, d);
    return std::pair{g, sign * (d[1].squaredNorm() + (d[0] - p).dot(d[2]))};
  });
}

namespace {

// Keeps the deepest candidate, and of equal ones the lowest u: the first, for the walk (its candidates
// come in increasing u), and the same one in whatever order the segments are examined (classifyPiece's
// nearest-first visit).
void consider(RodHit& best, double depth, double u) {
  if (depth > best.depth || (depth == best.depth && u < best.u)) {
    best.depth = depth;
    best.u = u;
  }
}

}  // namespace

void Rod::sectionHit(const Vec3& p, double u, bool fromBelow, RodHit& best) const {
  // r and r' alone (NurbsCurve computes them with the same operations whatever the order asked);
  // r'' only where r' may be too short for unitTangent, which then takes r'' (below 1e-14; any
  // threshold above that one gives the same tangent).
  Vec3 d[3];
  d[2] = Vec3::Zero();
  if (fromBelow) centerline_.derivativesFromBelow(u, 1, d);
  else centerline_.derivatives(u, 1, d);
  if (!(d[1].norm() > 1e-12)) evaluate(u, fromBelow, d);
  const Vec3 t = fromBelow ? unitTangentFromBelow(d[1], d[2]) : unitTangent(d[1], d[2]);
  const Vec3 w = p - d[0];
  // A zero of (r - p) . r' where r' vanishes (a cusp) is no section through p: p must lie in the plane.
  if (!(std::abs(w.dot(t)) <= 1e-7 * (1.0 + section_.boundingRadius()))) return;
  const Frame f = frame_.at(u, d[0], t);
  consider(best, 1.0 - section_.normalizedRadius(w.dot(f.d1), w.dot(f.d2)), u);
}

namespace {

// Within this distance beyond an end plane a point still counts as on the plane (section test).
double planeTolerance(double radius) { return 1e-9 * (1.0 + radius); }

}  // namespace

void Rod::classifyEnd(const Vec3& p, double u, const Vec3& point, const Vec3& outward, bool fromBelow, RodHit& best) const {
  const double beyond = (p - point).dot(outward);
  if (beyond < 0.0) return;  // in front of the plane: the crossings decide
  if (beyond > planeTolerance(section_.boundingRadius())) {
    if (caps_ == CapStyle::Round) consider(best, 1.0 - (point - p).norm() / section_.capRadius(), u);
    return;
  }
  sectionHit(p, u, fromBelow, best);
}

void Rod::classifySegment(const Vec3& p, const SmoothPiece& piece, std::size_t i, RodHit& best) const {
  const double radius = section_.boundingRadius();
  const double reach = radius + planeTolerance(radius);
  const double gap = distanceToSegment(p, samplePoint_[i], samplePoint_[i + 1]);
  if (gap - sampleDeviation_[i] > reach) return;  // no section of the segment reaches p
  auto g = [&](double u, bool fromBelow) {
    Vec3 d[2];
    if (fromBelow) centerline_.derivativesFromBelow(u, 1, d);
    else centerline_.derivatives(u, 1, d);
    return (d[0] - p).dot(d[1]);
  };
  auto gAt = [&](const Jet& j) { return (j.r - p).dot(j.d); };
  // Where r' vanishes (a repeated control point at a rod's end), g is 0 whatever p, so a zero of g next
  // to it has no sign change to bracket: from that end `still`, halve towards it until g takes the sign
  // `other` (the far end's g) does not. Only where g is exactly 0 (rare): other points keep their bits.
  auto stepOffStill = [&](double still, double far, double other, bool fromBelow, double& u, double& gu) {
    Vec3 d[2];
    if (fromBelow) centerline_.derivativesFromBelow(still, 1, d);
    else centerline_.derivatives(still, 1, d);
    if (d[1].norm() > 1e-12) return false;  // p lies on the section plane there: a zero, not a still end
    u = far;
    for (int k = 0; k < 64; ++k) {
      u = still + (u - still) * 0.5;
      gu = g(u, false);
      if (gu != 0.0 && (gu < 0.0) != (other < 0.0)) return true;
    }
    return false;
  };
  // Sections through p: the zeros of g(u) = (r(u) - p) . r'(u) on the segment.
  auto crossing = [&](double a, double b, double ga, double gb, bool belowB) {
    if (ga < 0.0 && gb > 0.0) {
      const double u = solveCrossing(p, a, b, 1.0);
      sectionHit(p, u, belowB && u == b, best);
    } else if (ga > 0.0 && gb < 0.0) {
      const double u = solveCrossing(p, a, b, -1.0);
      sectionHit(p, u, belowB && u == b, best);
    } else if (ga == 0.0 && a != piece.begin) {
      sectionHit(p, a, false, best);
    }
  };
  auto crossings = [&](double a, double b, double ga, double gb, bool belowB) {
    crossing(a, b, ga, gb, belowB);
    double u, gu;
    if (ga == 0.0 && gb != 0.0 && stepOffStill(a, b, gb, false, u, gu)) crossing(u, b, gu, gb, belowB);
    if (gb == 0.0 && ga != 0.0 && stepOffStill(b, a, ga, belowB, u, gu)) crossing(a, u, ga, gu, false);
  };
  const double a = sampleU_[i], b = sampleU_[i + 1];
  const bool belowB = piece.endFromBelow && i + 1 == piece.lastSample;
  const double ga = gAt(sampleJet_[i]), gb = belowB ? g(b, true) : gAt(sampleJet_[i + 1]);
  // g has one zero at most on the segment unless the curvature times the distance nears 1 (p close
  // to a centre of curvature): then look for every sign change on a finer sampling.
  const double chord = (samplePoint_[i + 1] - samplePoint_[i]).norm();
  if (sampleCurvature_[i] * (gap + sampleDeviation_[i] + chord) < 0.5) {
    crossings(a, b, ga, gb, belowB);
    return;
  }
  const std::size_t fold = foldOffset_[i];
  double x = a, gx = ga;
  for (int k = 1; k <= kFoldSubdivisions; ++k) {
    const double y = k == kFoldSubdivisions ? b : a + (b - a) * k / kFoldSubdivisions;
    const double gy = k == kFoldSubdivisions ? gb : fold != kNoFold ? gAt(foldJets_[fold + k - 1]) : g(y, false);
    crossings(x, y, gx, gy, belowB && k == kFoldSubdivisions);
    x = y;
    gx = gy;
  }
}

void Rod::classifyPiece(const Vec3& p, const SmoothPiece& piece, Walk walk, RodHit& best) const {
  const double radius = section_.boundingRadius();
  const double capReach = std::max(radius + planeTolerance(radius), section_.capRadius());
  if ((samplePoint_[piece.firstSample] - p).norm() <= capReach + sampleDeviation_[piece.firstSample])
    classifyEnd(p, piece.begin, piece.beginPoint, -piece.beginTangent, false, best);
  if (walk == Walk::EverySegment) {
    for (std::size_t i = piece.firstSample; i < piece.lastSample; ++i) classifySegment(p, piece, i, best);
  } else {
    // Nearest segment first, and none whose chord lies beyond the segments' reach (classifySegment
    // skips them) or whose every section through p would be shallower than the best candidate so far
    // (sectionDistanceLimit, asked at every node: recomputed when the best changed); `consider` makes
    // the order irrelevant to the result. Before any candidate is found only the reach bounds the
    // visit: without it, a point just outside the solid visited every segment whose box held it.
    double limitDepth = best.depth, limit = std::min(sectionDistanceLimit(best.depth), segmentReach_);
    segmentBoxes_.forEachNearestWithin(
        p, piece.firstSample, piece.lastSample,
        [&] {
          if (best.depth != limitDepth) {
            limitDepth = best.depth;
            limit = std::min(sectionDistanceLimit(best.depth), segmentReach_);
          }
          return limit;
        },
        [&](std::size_t i) { classifySegment(p, piece, i, best); });
  }
  if ((samplePoint_[piece.lastSample] - p).norm() <= capReach + sampleDeviation_[piece.lastSample - 1])
    classifyEnd(p, piece.end, piece.endPoint, piece.endTangent, piece.endFromBelow, best);
}

RodHit Rod::classifyPoint(const Vec3& p, Walk walk) const {
  RodHit best;
  best.depth = -std::numeric_limits<double>::infinity();
  best.u = centerline_.domainBegin();
  for (const SmoothPiece& piece : pieces_) classifyPiece(p, piece, walk, best);
  if (!(best.depth > -1.0)) best.depth = -1.0;
  best.inside = best.depth >= 0.0;
  return best;
}

// A non-finite coordinate is in no box, while the walk's arithmetic on it may still find a candidate
// (a NaN gap is never "too far"): such points take the walk.
RodHit Rod::classify(const Vec3& p) const { return classifyPoint(p, p.allFinite() ? Walk::Boxes : Walk::EverySegment); }

RodHit Rod::classifyWalkingEverySegment(const Vec3& p) const { return classifyPoint(p, Walk::EverySegment); }

double Rod::sectionDistanceLimit(double depth) const {
  // A section through p at u has p - r(u) within sectionHit's plane tolerance of its plane, so its
  // frame coordinates have a norm of at least |p - r(u)| - tolerance, and every section's gauge is at
  // least that norm over the bounding radius: its depth reaches `depth` only if |p - r(u)| <= radius
  // (1 - depth) + tolerance. distanceSlack_ holds the tolerance with room for every rounding; the
  // relative term, the rounding of the depth's own scale.
  const double radius = section_.boundingRadius(), shortfall = 1.0 - depth;
  return radius * shortfall + distanceSlack_ + 1e-9 * radius * std::abs(shortfall);
}

namespace {

// The hulls' rounding margin (`scale`: the largest coordinate, reach and deviation): their Bezier
// points and the curve's evaluation round within a few ulps of the largest control coordinate times
// the weights' ratio (rational curves), far below 1e-13 of it; the query's distances (p within a
// reach box) within a few ulps of the scale, far below the usual 1e-9 of it.
double hullMargin(const NurbsCurve& centerline, double scale) {
  const std::vector<double>& w = centerline.weights();
  const auto [lightest, heaviest] = std::minmax_element(w.begin(), w.end());
  double largestControl = 0.0;
  for (const Vec3& q : centerline.points()) largestControl = std::max(largestControl, q.cwiseAbs().maxCoeff());
  return 1e-9 * (1.0 + scale + largestControl) + 1e-13 * (*heaviest / *lightest) * largestControl;
}

}  // namespace

void Rod::buildSegmentBoxes() {
  // A segment is examined when its computed distance to p, less its deviation, is at most the reach
  // (classifySegment). The computed distance is that of p to a point within a few ulps of the segment,
  // so it is below the true distance by at most ~10 eps (|p| + |sample|) <= ~10 eps (distance + 2
  // |sample|); the margin of 1e-9 relative to the coordinates, the reach and the deviation is far
  // above it, so a p outside the grown box (on any axis) is one the walk skips too.
  const double radius = section_.boundingRadius();
  const double reach = radius + planeTolerance(radius);
  double largest = 0.0, maxDeviation = 0.0;
  for (const Vec3& q : samplePoint_) largest = std::max(largest, q.cwiseAbs().maxCoeff());
  for (const double dev : sampleDeviation_) maxDeviation = std::max(maxDeviation, dev);
  const double margin = 1e-9 * (1.0 + largest + reach + maxDeviation);
  std::vector<Box3> boxes(sampleDeviation_.size());
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    const double grow = sampleDeviation_[i] + reach + margin;
    boxes[i] = Box3(Vec3(samplePoint_[i].cwiseMin(samplePoint_[i + 1]).array() - grow),
                    Vec3(samplePoint_[i].cwiseMax(samplePoint_[i + 1]).array() + grow));
  }
  const double hullSlack = hullMargin(centerline_, largest + reach + maxDeviation);
  segmentBoxes_ = SegmentBoxes(std::move(boxes), segmentHulls(hullSlack), hullSlack);
  // A segment whose chord lies farther than this from p is one classifySegment skips (its computed gap
  // less its deviation is beyond the reach); its hull holds the chord, so the hull's computed distance
  // exceeds this too (the hulls' margin covers the two distances' rounding).
  segmentReach_ = reach + maxDeviation + margin;
  // sectionHit's plane tolerance (1e-7 (1 + radius)) doubled, and the reach boxes' margin for the
  // rounding of the distances and frame coordinates.
  distanceSlack_ = 2e-7 * (1.0 + radius) + margin;
}

std::vector<SegmentBoxes::Capsule> Rod::segmentHulls(double margin) const {
  // Every centerline point classifySegment can take a section at, r(u) for u in the segment's [a, b]
  // (from below or above at b), lies in the convex hull of the segment's Bezier control points, so
  // within their largest distance from the chord (NurbsCurve::deviationOn; a rigorous bound, unlike
  // sampleDeviation_), or is a sample point, an end of the chord.
  std::vector<SegmentBoxes::Capsule> hulls(sampleDeviation_.size());
  for (std::size_t i = 0; i < hulls.size(); ++i) {
    const Vec3 &a = samplePoint_[i], &b = samplePoint_[i + 1];
    hulls[i] = {a, b, centerline_.deviationOn(sampleU_[i], sampleU_[i + 1], a, b) + margin};
  }
  return hulls;
}

}  // namespace rodfab::geometry
