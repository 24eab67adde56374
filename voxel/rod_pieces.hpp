// The rasterizer's per-rod representation (internal to voxel/): the rod cut into short pieces by the
// normal planes of its centerline, each with a cheap approximation of the frame coordinates of any
// point between its two planes and a measured bound on that approximation's error.
#pragma once

#include "geometry/rod.hpp"
#include "voxel/printer_grid.hpp"

#include <functional>
#include <vector>

namespace rodfab::voxel::detail {

// An affine function of the voxel index. Always evaluated as row(j, k) + gx * i, so two pieces that
// share a plane compute bit-identical values at every voxel and split space without gaps or overlap.
struct AffineInIndex {
  double c = 0.0, gx = 0.0, gy = 0.0, gz = 0.0;

  double row(int j, int k) const { return (c + gy * j) + gz * k; }
  double at(int i, int j, int k) const { return row(j, k) + gx * i; }
};

// f(p) = n . (p - q) for world points p, as a function of the voxel index of p.
AffineInIndex affineInIndex(const PrinterGrid& grid, const geometry::Vec3& n, const geometry::Vec3& q);

// Approximation accuracy asked of every swept piece (mm, in frame coordinates). Voxel centres whose
// approximate position is within the piece's measured bound of the section boundary are decided by
// the exact test instead, so the tolerance only trades piece count against exact evaluations.
constexpr double kCoordinateTolerance = 1e-4;

struct RodPiece {
  enum class Kind : unsigned char { Swept, BeginCap, EndCap, Exact };
  Kind kind = Kind::Swept;
  // Swept: voxels with planes[plane].at >= 0 and planes[plane + 1].at < 0 (between the normal planes
  // at u[plane] and u[plane + 1]). BeginCap: planes[plane].at < 0. EndCap: planes[plane].at >= 0 (the
  // first and last plane of a smooth piece). Exact: no plane; every voxel within `reach` of the chord
  // goes to the exact test (pieces whose approximation could not be bounded: tight bends, where the
  // normal planes cross inside the rod, cusps, jumps of E).
  int plane = 0;

  // Swept: frame coordinates measured in the two bounding planes, blended by the position
  // lambda = a / (a - b) between them, plus a lambda (1 - lambda) curvature correction.
  AffineInIndex x1Begin, x2Begin, x1End, x2End;
  double x1Quadratic = 0.0, x2Quadratic = 0.0;
  // E: modulusBegin + lambda (modulusEnd - modulusBegin) + lambda (1 - lambda) (modulusQuadratic +
  // modulusAcross1 x1 + modulusAcross2 x2) (modulusBlend): the terms in x1, x2 follow how lambda drifts
  // from the section's own position across it where the curvature changes along the piece; they are 0
  // where E meets its tolerance without them.
  double modulusBegin = 0.0, modulusEnd = 0.0, modulusQuadratic = 0.0;
  double modulusAcross1 = 0.0, modulusAcross2 = 0.0;
  // The exact E's bounds on the piece (BSplineField::valueBoundsOn): the estimate is held within them,
  // so a voxel never asks for a modulus outside what the design asks for there.
  double modulusLow = 0.0, modulusHigh = 0.0;
  // Bound on the normalized-radius error of the approximation (inf where it could not be bounded).
  double normalizedRadiusErrorBound = 0.0;

  // Round caps: the components of p - (centerline end point), one affine function per world axis, and E there.
  AffineInIndex capOffset[3];
  float capModulus = 0.0f;

  // Every voxel the piece can own lies within `reach` (mm) of the line through `axisPoint` along
  // `axisDirection` (the chord for swept and exact pieces, the end tangent for caps) and inside `box`.
  geometry::Vec3 axisPoint, axisDirection;
  double reach = 0.0;
  openvdb::CoordBBox box;
};

struct RodPieces {
  std::vector<AffineInIndex> planes;  // one chain per smooth piece of the rod, in order
  std::vector<RodPiece> pieces;
  openvdb::CoordBBox box;  // union of the pieces' boxes
  double inverseHalfWidth = 0.0, inverseHalfHeight = 0.0, inverseCapRadius = 0.0;
};

// Shortest piece the refinement makes (mm) on a grid: a quarter of the smallest voxel edge. Below it
// an approximation that still misses its tolerance keeps its measured bound (more voxels go to the
// exact test), so tight bends, cusps and round-off far from the origin cannot refine without end.
double minimumPieceLength(const PrinterGrid& grid);
// Most pieces one rod is cut into: 8 per polyline segment plus 4 per minimumPieceLength of its length,
// plus its caps (E varying steeply along a tightly bent rod needs some 500 pieces per mm). The
// refinement stops splitting when it is reached.
std::size_t pieceBudget(const geometry::Rod& rod, const PrinterGrid& grid);

// Cuts `rod` into pieces, refining each until its measured coordinate error is below
// kCoordinateTolerance, or it is shorter than minimumPieceLength, or the rod's pieceBudget is spent.
// Calls `interrupted` (if set) every few milliseconds of work and throws voxel::Interrupted when it
// returns true.
RodPieces buildRodPieces(const geometry::Rod& rod, const PrinterGrid& grid, const std::function<bool()>& interrupted = {});

// The swept-piece approximation at a point with plane values a >= 0 > b and frame coordinates
// measured in the begin and end planes; shared by the rasterizer and the error measurement. T is
// double, or a vector of doubles (GCC vector extension) for several voxels at once: the same IEEE
// operations lane by lane, so every lane gets the bits the scalar expressions give (as long as the
// compiler fuses no multiply-add, as on baseline x86-64, which has no FMA).
template <typename T>
struct SweptEstimateOf {
  T lambda, x1, x2;
};
using SweptEstimate = SweptEstimateOf<double>;
// `Piece` is RodPiece or anything with its x1Quadratic, x2Quadratic (and, for the modulus, modulusBegin, modulusEnd,
// modulusQuadratic, modulusLow, modulusHigh).
template <typename T, typename Piece = RodPiece>
inline SweptEstimateOf<T> estimateSwept(const Piece& piece, T a, T b, T x1Begin, T x2Begin, T x1End, T x2End) {
  const T lambda = a / (a - b);
  const T quadraticWeight = lambda * (1.0 - lambda);
  return {lambda, x1Begin + lambda * (x1End - x1Begin) + quadraticWeight * piece.x1Quadratic,
          x2Begin + lambda * (x2End - x2Begin) + quadraticWeight * piece.x2Quadratic};
}
// E at a point of the piece before the clamp: the blend of E at the planes plus lambda (1 - lambda)
// times modulusQuadratic and the terms in x1, x2 (RodPiece). Across false leaves those terms out: the
// same bits where they are 0 (q + 0 is q), four vector operations fewer per quad in the voxel loop.
// A `Piece` may hold modulusRise = modulusEnd - modulusBegin ready (voxel::detail::SweptLanes).
template <bool Across = true, typename T, typename Piece>
inline T modulusBlend(const Piece& piece, const SweptEstimateOf<T>& at) {
  const auto rise = [&] {
    if constexpr (requires { piece.modulusRise; }) return piece.modulusRise;
    else return piece.modulusEnd - piece.modulusBegin;
  }();
  const T lambda = at.lambda;
  if constexpr (Across)
    return piece.modulusBegin + lambda * rise +
           lambda * (1.0 - lambda) * (piece.modulusQuadratic + (piece.modulusAcross1 * at.x1 + piece.modulusAcross2 * at.x2));
  else
    return piece.modulusBegin + lambda * rise + lambda * (1.0 - lambda) * piece.modulusQuadratic;
}
// The blend held within the piece's E bounds. A `Piece` may hold them in lanes ready (modulusFloor =
// T{} + modulusLow, modulusCeiling = T{} + modulusHigh): the same values, so the same bits, where
// computing them for every quad cost vector instructions.
template <bool Across = true, typename T, typename Piece>
inline T estimateModulus(const Piece& piece, const SweptEstimateOf<T>& at) {
  const T e = modulusBlend<Across>(piece, at);
  T low, high;
  if constexpr (requires { piece.modulusFloor; }) {
    low = piece.modulusFloor;
    high = piece.modulusCeiling;
  } else {
    low = T{} + piece.modulusLow;
    high = T{} + piece.modulusHigh;
  }
  const T above = e < low ? low : e;
  return above > high ? high : above;
}

}  // namespace rodfab::voxel::detail
