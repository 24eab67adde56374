// A rod (centerline, section, frame, caps, E(s)) and the queries the voxelizer runs per voxel:
// closest point on the centerline and the inside test with its normalized depth.
#pragma once

#include "geometry/frame.hpp"
#include "geometry/mechanics_spec.hpp"
#include "geometry/nurbs.hpp"
#include "geometry/section.hpp"

#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace rodfab::geometry {

using Box3 = Eigen::AlignedBox3d;

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
  // 1 on the centerline, 0 on the boundary, negative outside: 1 - Section::normalizedRadius in the
  // swept part, 1 - distance / capRadius in a round cap. Ranks overlapping rods at joints.
  double depth = -1.0;
  double u = 0.0;  // centerline parameter the value E(u) is taken at
};

class Rod {
public:
  Rod() = default;
  // Exactly one of `referenceNormal` / `orientation` may be given; neither is fine for circles (a
  // rotation-minimizing frame with an arbitrary seed is used then). Throws std::invalid_argument on
  // inconsistent input; the design reader validates first and reports user-facing errors.
  Rod(std::string name, NurbsCurve centerline, Section section, std::optional<Vec3> referenceNormal,
      std::optional<QuaternionSpline> orientation, CapStyle caps, BSplineField modulus);

  const std::string& name() const { return name_; }
  const NurbsCurve& centerline() const { return centerline_; }
  const Section& section() const { return section_; }
  const RodFrame& frame() const { return frame_; }
  const std::optional<Vec3>& referenceNormal() const { return referenceNormal_; }
  const std::optional<QuaternionSpline>& orientation() const { return orientation_; }
  CapStyle caps() const { return caps_; }
  const BSplineField& modulus() const { return modulus_; }
  double length() const { return length_; }

  // Parameters of a polyline that follows the centerline within `sampleDeviation()` (mm): the seeds
  // of closest-point searches and a cheap way for callers to visit the rod piece by piece.
  const std::vector<double>& sampleParameters() const { return sampleU_; }
  const std::vector<Vec3>& samplePoints() const { return samplePoint_; }
  // Upper bound on the distance between the polyline segment [i, i+1] and the curve over it.
  double sampleDeviation(std::size_t segment) const { return sampleDeviation_[segment]; }

  // Global closest point (all polyline segments that could hold it are refined; robust for points
  // equidistant from two spans and at the ends).
  ClosestPoint closestPoint(const Vec3& p) const;
  // Closest point restricted to [a, b], by safeguarded Newton on (r(u) - p) . r'(u) = 0.
  ClosestPoint closestPointInInterval(const Vec3& p, double a, double b) const;

  // Inside test through the closest point: section in frame coordinates, plus the end caps.
  RodHit classify(const Vec3& p) const;
  RodHit classify(const Vec3& p, const ClosestPoint& closest) const;

  // Axis-aligned box containing the whole solid (sections and caps).
  Box3 bounds() const { return bounds_; }

private:
  void sampleCenterline();
  void computeBounds();

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
  Box3 bounds_;
};

struct RodStructure {
  std::string source;  // where it was read from, for messages
  std::vector<Rod> rods;
  MechanicsSpec mechanics;  // loads and supports for `rodfab simulate`; ignored by the slicer

  Box3 bounds() const;
};

// What `rodfab validate` prints.
struct DesignSummary {
  std::size_t rodCount = 0;
  double totalLength = 0.0;  // mm, centerline arc length
  Box3 bounds;               // mm, including sections and caps
  double modulusMin = 0.0, modulusMax = 0.0;  // MPa, sampled along every rod
  std::size_t circles = 0, ellipses = 0, rectangles = 0;
  std::size_t roundCaps = 0, flatCaps = 0;
};
DesignSummary summarize(const RodStructure& structure);

}  // namespace rodfab::geometry
