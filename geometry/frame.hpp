// Cross-section frames along a centerline: rotation-minimizing from a reference normal, or a
// quaternion B-spline as produced by Cosserat rod solvers.
#pragma once

#include "geometry/nurbs.hpp"

#include <Eigen/Geometry>

#include <vector>

namespace rodfab::geometry {

// A rotation-minimizing frame keeps the fewest samples a knot span (4, 8, ..., kMaxSamplesPerSpan)
// whose d1 agrees with that of twice as many within kFrameTolerance (rad) at every sample; never more
// a span than keep it within kMaxFrameSamples in all (but at least 4 a span). Curves that bend and
// twist sharply within a span stop at kMaxSamplesPerSpan short of the tolerance (their estimated error
// says by how much): more samples would cost them 4x the memory for no voxel of a print.
inline constexpr double kFrameTolerance = 1e-10;
inline constexpr int kMaxSamplesPerSpan = 64;
inline constexpr std::size_t kMaxFrameSamples = 1 << 16;

// Orthonormal, right-handed: d3 is the unit tangent, d1 and d2 span the cross-section plane.
struct Frame {
  Vec3 d1, d2, d3;
};

// q(u) = sum N_i(u) q_i, normalized at evaluation. Quaternions are (w, x, y, z).
class QuaternionSpline {
public:
  QuaternionSpline() = default;
  // Throws std::invalid_argument for bad counts or a zero or non-finite quaternion.
  QuaternionSpline(int degree, std::vector<double> knots, std::vector<Eigen::Vector4d> quaternions);

  int degree() const { return degree_; }
  const std::vector<double>& knots() const { return knots_; }
  const std::vector<Eigen::Vector4d>& quaternions() const { return quaternions_; }
  double domainBegin() const { return knots_[degree_]; }
  double domainEnd() const { return knots_[quaternions_.size()]; }

  // The unit rotation at u: the blend of the control quaternions, normalized. Works for components
  // of any finite magnitude (1e-150 .. 1e300); a blend that cancels to zero gives the identity.
  Eigen::Quaterniond rotation(double u) const;

private:
  int degree_ = 0;
  std::vector<double> knots_;
  std::vector<Eigen::Vector4d> quaternions_;
  std::vector<Eigen::Vector4d> scaledQuaternions_;  // times one power of two: largest component in [1, 2)
};

// The frame field of one rod. Both kinds are evaluated at a centerline point already known to the
// caller (the voxelizer has r(u) and r'(u) from its closest-point search), so no curve work repeats.
class RodFrame {
public:
  enum class Kind { RotationMinimizing, Orientation };

  RodFrame() = default;
  // Rotation-minimizing frame (double reflection, Wang et al. 2008) seeded with d1 = the reference
  // normal projected onto the first cross-section plane. The normal's magnitude does not matter (any
  // finite non-zero vector). Samples a span: see kFrameTolerance; estimatedError() says how far the
  // kept frames are from the exact RMF. Throws std::invalid_argument if the normal is zero or not
  // finite, or parallel to the initial tangent (within 1e-9 rad).
  static RodFrame rotationMinimizing(const NurbsCurve& curve, const Vec3& referenceNormal);
  // d1, d2 from the rotation q(u); they are projected onto the plane normal to the tangent so the
  // cross-section stays perpendicular to the centerline even where the solver's frame shears.
  static RodFrame fromOrientation(const NurbsCurve& curve, QuaternionSpline orientation);

  Kind kind() const { return kind_; }
  const QuaternionSpline& orientation() const { return orientation_; }
  // Rotation-minimizing: the largest angle (rad) between a sample's d1 and the exact RMF's, estimated
  // from the frames at twice the samples (double reflection's error being fourth order in the step);
  // 0 for the orientation kind. Frames between samples add one double-reflection step, whose error is
  // of fifth order.
  double estimatedError() const { return estimatedError_; }
  // Rotation-minimizing: the number of samples kept (their memory is ~80 bytes each).
  std::size_t sampleCount() const { return sampleU_.size(); }

  // Frame at parameter u, where `point` = r(u) and `unitTangent` = r'(u)/|r'(u)|.
  Frame at(double u, const Vec3& point, const Vec3& unitTangent) const;
  // Convenience overload that evaluates the curve.
  Frame at(const NurbsCurve& curve, double u) const;

private:
  Kind kind_ = Kind::RotationMinimizing;
  // Rotation-minimizing: frames at a dense parameter sampling; between samples one more double
  // reflection step from the sample below, which is how the samples themselves were propagated.
  std::vector<double> sampleU_;
  std::vector<Vec3> samplePoint_, sampleTangent_, sampleD1_;
  double estimatedError_ = 0.0;
  QuaternionSpline orientation_;
};

// Unit tangent r'/|r'|, falling back to the second derivative where r' vanishes (a cusp-free
// curve with a zero-length first derivative at a clamped end).
Vec3 unitTangent(const Vec3& firstDerivative, const Vec3& secondDerivative);
// The same for derivatives taken from below (NurbsCurve::derivativesFromBelow): where r' vanishes
// the curve arrives along -r''.
Vec3 unitTangentFromBelow(const Vec3& firstDerivative, const Vec3& secondDerivative);

// Euclidean norm without overflow or underflow for any finite components (0 for a zero vector,
// inf or NaN when a component is).
double stableNorm(const Eigen::Ref<const Eigen::VectorXd>& v);
// `v` times 2^-e, 2^e <= the largest |component| < 2^(e+1) (`v` itself when zero or not finite): exact,
// a direction kept, the largest component in [1, 2), for denormal and huge components alike.
Vec3 scaledToUnitOrder(const Vec3& v);

}  // namespace rodfab::geometry
