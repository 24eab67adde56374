// A rod (centerline, section, frame, caps, E(s)) and the queries the voxelizer runs per voxel:
// the inside test with its normalized depth, closest points, and the rod's bounding box.
//
// The rod's solid (what `classify` and the voxelizer decide, and `bounds` contains):
//   The centerline is cut at its C0 points into smooth pieces. A C0 point is an interior knot where the
//   unit tangents from below and from above differ by more than kKinkTolerance: the vertices of a
//   degree-1 polyline, a knot of multiplicity = degree with control points not in line, a cusp at a
//   knot. The solid is the union over the pieces of
//     - the swept section: every p = r(u) + x1 d1(u) + x2 d2(u) with u in the piece and (x1, x2) in the
//       section (in the normal plane at u, frame coordinates as in geometry/frame.hpp), and
//     - the caps at both ends of every piece, in the rod's CapStyle at its C0 points too: Round adds the
//       half-ball of radius Section::capRadius() beyond the piece's end plane (so a round-capped rod gets
//       a ball joint at each kink and no notch), Flat adds nothing (a kink's outer side is notched).
//   Where the section's bounding radius is below the radius of curvature and the rod does not come back
//   within its own reach (every printable rod we know), a point lies in the section at one u only, its
//   closest centerline point: this is the closest-point rule, decided with one Newton solve.
//   depth = the largest over the sections and caps holding p of 1 - Section::normalizedRadius (swept) or
//   1 - distance / capRadius (caps); E is taken at the u of the deepest (on exact ties, the lowest u).
#pragma once
#include "geometry/frame.hpp"
#include "geometry/nurbs.hpp"
#include "geometry/section.hpp"
#include "geometry/segment_boxes.hpp"

#include <Eigen/Geometry>

#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

namespace rodfab::geometry {

using Box3 = Eigen::AlignedBox3d;

// Largest |coordinate| of a control point the design reader accepts (mm): double precision then still
// resolves positions to 1e-7 mm.
inline constexpr double kMaxCoordinateMm = 1e9;
// Tangents from below and above an interior knot farther apart than this (|t- - t+|, about the angle in
// radians) make the knot a C0 point.
inline constexpr double kKinkTolerance = 1e-7;
// Most control points (or control values) one spline of a design may have; the design reader refuses
// more. A rod is sampled, framed and integrated span by span, so the work grows with its spans: a
// degree-7 zigzag of 16,384 spans takes ~7 s to validate, of 100,000 spans minutes.
inline constexpr std::size_t kMaxSplineControls = 16384;
// Most polyline samples (sampleParameters) one rod may need; the constructor throws beyond. Each costs
// about 64 bytes plus the rasterizer's pieces over it.
inline constexpr std::size_t kMaxSamplesPerRod = std::size_t(1) << 20;

enum class CapStyle {
  Round,  // a half-ball of radius Section::capRadius() on each end, so rods meeting at a joint leave no notch
  Flat,   // the swept section ends in the planes normal to the end tangents
};

struct ClosestPoint {
  double u = 0.0;        // parameter of the closest centerline point
  Vec3 point;            // r(u)
  Vec3 tangent;          // unit tangent at u
  double distance = 0.0; // |p - r(u)|
};

// Where a query point lies relative to one rod.
struct RodHit {
  bool inside = false;
  // 1 on the centerline, 0 on the boundary, negative outside: the largest 1 - Section::normalizedRadius
  // over the sections through the point, or 1 - distance / capRadius in a round cap. Ranks overlapping
  // rods at joints. -1 when no section or cap comes near the point.
  double depth = -1.0;
  double u = 0.0;  // centerline parameter the value E(u) is taken at
};

// A part of the centerline between C0 points (see the top of this file).
struct SmoothPiece {
  double begin = 0.0, end = 0.0;                // its parameter interval
  std::size_t firstSample = 0, lastSample = 0;  // sampleParameters()[firstSample] == begin, [lastSample] == end
  Vec3 beginPoint, endPoint;                    // r at its ends (from below at a C0 end)
  Vec3 beginTangent, endTangent;                // unit tangents at its ends, taken inside the piece
  bool endFromBelow = false;                    // `end` is a C0 point: evaluate there from below
};

// What a rod's centerline cannot be: of zero or non-finite length, or too intricate to sample.
class CenterlineError : public std::invalid_argument {
public:
  using std::invalid_argument::invalid_argument;
};

class Rod {
public:
  Rod() = default;
  // Exactly one of `referenceNormal` / `orientation` may be given; neither is fine for circles (a
  // rotation-minimizing frame with an arbitrary seed is used then). Throws std::invalid_argument on
  // inconsistent input (the design reader validates first and reports user-facing errors), and
  // CenterlineError when the centerline's length is not finite or is zero (below 1e-9 of its control
  // points' extent) or when it needs more than kMaxSamplesPerRod samples (the message names the rod).
  // The arc length of `centerline` (mm), as a Rod of it has; throws CenterlineError when it is not
  // finite or is zero (below 1e-9 of the control points' extent, at least 1e-9 mm).
  static double checkedLength(const NurbsCurve& centerline);
  Rod(std::string name, NurbsCurve centerline, Section section, std::optional<Vec3> referenceNormal,
      std::optional<QuaternionSpline> orientation, CapStyle caps, BSplineField modulus);
  // A rod's samples take 0.1-1 MB on a winding centerline. Its moves do not throw (Eigen's AlignedBox, the
  // bounds, is a copy of doubles but does not say so): std::vector<Rod> moves its rods when it grows
  // instead of copying every one (a 2,000-rod design read from CAD held 1.5 GB instead of ~0.6 GB).
  Rod(const Rod&) = default;
  Rod& operator=(const Rod&) = default;
  Rod(Rod&&) noexcept = default;
  Rod& operator=(Rod&&) noexcept = default;

  const std::string& name() const { return name_; }
  const NurbsCurve& centerline() const { return centerline_; }
  const Section& section() const { return section_; }
  const RodFrame& frame() const { return frame_; }
  const std::optional<Vec3>& referenceNormal() const { return referenceNormal_; }
  const std::optional<QuaternionSpline>& orientation() const { return orientation_; }
  CapStyle caps() const { return caps_; }
  const BSplineField& modulus() const { return modulus_; }
  double length() const { return length_; }

  // Parameters of a polyline that follows the centerline within a bounded deviation: the seeds of
  // closest-point searches and a cheap way for callers to visit the rod piece by piece. Every knot
  // and so every C0 point is a sample; the segments turn by at most ~10 degrees where the curve could
  // be resolved (sampleResolved).
  const std::vector<double>& sampleParameters() const { return sampleU_; }
  // Estimated upper bound on the curvature (1/mm) over segment i: twice the largest sampled; infinite
  // where the curve's speed vanishes or the segment is unresolved.
  double sampleCurvature(std::size_t segment) const { return sampleCurvature_[segment]; }
  // False where the adaptive sampling hit its depth limit (a cusp, extreme weights): the segment's
  // deviation and curvature bounds are then unreliable and its callers take the safe path.
  bool sampleResolved(std::size_t segment) const { return sampleCurvature_[segment] < kUnresolved; }
  // The smooth pieces, in parameter order (one for a C1 centerline).
  const std::vector<SmoothPiece>& smoothPieces() const { return pieces_; }

  // Global closest point on the centerline (all polyline segments that could hold it are refined;
  // robust for points equidistant from two spans and at the ends).
  ClosestPoint closestPoint(const Vec3& p) const;
  // Closest point restricted to [a, b], by safeguarded Newton on (r(u) - p) . r'(u) = 0.
  ClosestPoint closestPointInInterval(const Vec3& p, double a, double b) const;

  // The inside test of the solid defined at the top of this file. Thread-safe (const, no caches).
  // Examines only the sample segments whose box (segment, deviation and section reach, plus a margin
  // for rounding) holds p, nearest first, and of those only the ones whose hull (a capsule around the
  // chord holding the segment's centerline, NurbsCurve::deviationOn) is close enough to p for the
  // segment to reach p at all and for a section there to be as deep as the best found so far: the
  // others cannot change the answer, and ties go to the lowest u in any order, so it returns the
  // walk's bits. A rod that comes back within its own reach (a coil tighter than its section) thus
  // costs the few segments near p, not every turn within reach.
  RodHit classify(const Vec3& p) const;
  // The same test examining every sample segment of every smooth piece: the reference `classify`
  // equals bit for bit (tests, benchmarks). It also answers points with a non-finite coordinate.
  RodHit classifyWalkingEverySegment(const Vec3& p) const;

  // Axis-aligned box containing the whole solid (sections and caps of every smooth piece).
  Box3 bounds() const { return bounds_; }

private:
  static constexpr double kUnresolved = std::numeric_limits<double>::max();

  void findSmoothPieces(const std::vector<double>& breakpoints, std::vector<bool>& isC0) const;
  void sampleCenterline();
  void estimateCurvature(const std::vector<bool>& unresolved);
  void cacheJets();
  void computeBounds();
  // r, r', r'' at u; from below when `fromBelow` (the end of a piece at a C0 point).
  void evaluate(double u, bool fromBelow, Vec3* d) const;
  // Section test at parameter u of `piece`: depth and u, or nothing if p is farther than the section reaches.
  void sectionHit(const Vec3& p, double u, bool fromBelow, RodHit& best) const;
  // Zeros of g(u) = (r(u) - p) . r'(u) on [a, b] with g(a) = ga, g(b) = gb of opposite signs.
  double solveCrossing(const Vec3& p, double a, double b, double sign) const;
  // The piece's end plane at u through r(u) = `point` (outward normal `outward`): the cap beyond it,
  // the section on it.
  void classifyEnd(const Vec3& p, double u, const Vec3& point, const Vec3& outward, bool fromBelow, RodHit& best) const;
  // The sections through p of sample segment i of `piece`, if the segment can reach p.
  void classifySegment(const Vec3& p, const SmoothPiece& piece, std::size_t i, RodHit& best) const;
  // Which of a piece's segments classifyPiece examines: those whose boxes hold the point
  // (segmentBoxes_), or every one (the reference walk).
  enum class Walk { Boxes, EverySegment };
  void classifyPiece(const Vec3& p, const SmoothPiece& piece, Walk walk, RodHit& best) const;
  RodHit classifyPoint(const Vec3& p, Walk walk) const;
  // How far (mm) a centerline point may lie from p for a section through p there to have a depth of
  // at least `depth` (a bound with room for rounding; infinite for -inf).
  double sectionDistanceLimit(double depth) const;
  void buildSegmentBoxes();
  // Capsules holding every centerline point of each sample segment (the nearest-first visit's
  // distances): its chord grown by the Bezier control points' deviation from it and by `margin`.
  std::vector<SegmentBoxes::Capsule> segmentHulls(double margin) const;

  std::string name_;
  NurbsCurve centerline_;
  Section section_;
  std::optional<Vec3> referenceNormal_;
  std::optional<QuaternionSpline> orientation_;
  RodFrame frame_;
  CapStyle caps_ = CapStyle::Round;
  BSplineField modulus_;
  double length_ = 0.0;
  std::vector<double> sampleU_;
  std::vector<Vec3> samplePoint_;
  std::vector<double> sampleDeviation_;
  std::vector<double> sampleCurvature_;
  // r(u) and r'(u) (from above) at every sample, and at the 7 inner sub-points of the segments where
  // the inside test may subdivide (foldOffset_ per segment into foldJets_, or kNoFold): the test's
  // sign checks then cost a dot product.
  struct Jet {
    Vec3 r, d;
  };
  static constexpr std::size_t kNoFold = std::numeric_limits<std::size_t>::max();
  std::vector<Jet> sampleJet_;
  std::vector<std::size_t> foldOffset_;
  std::vector<Jet> foldJets_;
  std::vector<SmoothPiece> pieces_;
  // Segment i's box: its end points grown by its deviation, the section's reach and a rounding margin;
  // and its hull (segmentHulls).
  SegmentBoxes segmentBoxes_;
  double distanceSlack_ = 0.0;  // sectionDistanceLimit's allowance for the plane tolerance and rounding
  double segmentReach_ = 0.0;   // farthest a segment's chord may lie from p for classifySegment to examine it
  Box3 bounds_;
};

static_assert(std::is_nothrow_move_constructible_v<Rod> && std::is_nothrow_move_assignable_v<Rod>);

struct RodStructure {
  std::string source;  // where it was read from, for messages
  std::vector<Rod> rods;

  Box3 bounds() const;
};

// What `rodfab validate` prints. Empty: no rods, an empty box, modulusMin +inf and modulusMax -inf.
struct DesignSummary {
  std::size_t rodCount = 0;
  double totalLength = 0.0;  // mm, centerline arc length
  Box3 bounds = Box3();      // mm, including sections and caps
  double modulusMin = std::numeric_limits<double>::infinity(), modulusMax = -std::numeric_limits<double>::infinity();  // MPa, sampled along every rod
  std::size_t circles = 0, ellipses = 0, rectangles = 0;
  std::size_t roundCaps = 0, flatCaps = 0;
  // rad: the largest estimated error of a rod's rotation-minimizing frame (RodFrame::estimatedError).
  double frameError = 0.0;

  void add(const Rod& rod);              // counts one more rod
  void add(const DesignSummary& later);  // counts the rods `later` counted, after these (lengths summed in that order)
};
// The rods counted in order: the same figures whether the rods are kept (here) or summarized as they
// are read and let go (summarizeDesign, design_file.hpp).
DesignSummary summarize(const RodStructure& structure);

}  // namespace rodfab::geometry
