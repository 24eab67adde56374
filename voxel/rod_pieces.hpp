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
  // lambda = a / (a - b) between them, plus a lambda (1 - lambda) curvature correction: a constant, and
  // terms in the blended coordinates themselves (x1Across1 x1 + x1Across2 x2 for x1, and so on; see
  // estimateSwept) where the coordinates miss their tolerance without them.
  AffineInIndex x1Begin, x2Begin, x1End, x2End;
  double x1Quadratic = 0.0, x2Quadratic = 0.0;
  double x1Across1 = 0.0, x1Across2 = 0.0, x2Across1 = 0.0, x2Across2 = 0.0;
  // E: modulusBegin + lambda (modulusEnd - modulusBegin) + lambda (1 - lambda) (modulusQuadratic +
  // modulusCubic (lambda - 1/2) + modulusAcross1 x1 + modulusAcross2 x2) (modulusBlend). The cubic term
  // follows how lambda strays from the centerline's parameter along the axis, the terms in x1, x2 how it
  // drifts across the section where the curvature changes along the piece; all three are 0 where E
  // meets its tolerance without them.
  double modulusBegin = 0.0, modulusEnd = 0.0, modulusQuadratic = 0.0;
  double modulusCubic = 0.0, modulusAcross1 = 0.0, modulusAcross2 = 0.0;
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
// kCoordinateTolerance and E's below its tolerance (1e-6 relative), or it is shorter than
// minimumPieceLength, or the rod's pieceBudget is spent. A piece accurate only with the full estimate's
// terms (needsFullEstimate) is split as well where two halves would cost the voxel loop less.
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
// `Piece` is RodPiece or anything with its x1Quadratic, x2Quadratic, x1Across1 ... x2Across2 (and, for
// the modulus, modulusBegin, modulusEnd, modulusQuadratic, modulusCubic, modulusAcross1, 2, modulusLow,
// modulusHigh). Full false leaves the terms beyond the blends and the constant quadratic terms out (the
// coordinates' terms across, E's cubic term and terms across): the same bits where they are 0, fifteen
// vector operations fewer per quad in the voxel loop (eight for the coordinates, seven for E).
template <bool Full = true, typename T, typename Piece = RodPiece>
inline SweptEstimateOf<T> estimateSwept(const Piece& piece, T a, T b, T x1Begin, T x2Begin, T x1End, T x2End) {
  const T lambda = a / (a - b);
  const T quadraticWeight = lambda * (1.0 - lambda);
  const T x1 = x1Begin + lambda * (x1End - x1Begin), x2 = x2Begin + lambda * (x2End - x2Begin);
  if constexpr (Full)
    return {lambda, x1 + quadraticWeight * (piece.x1Quadratic + (piece.x1Across1 * x1 + piece.x1Across2 * x2)),
            x2 + quadraticWeight * (piece.x2Quadratic + (piece.x2Across1 * x1 + piece.x2Across2 * x2))};
  else
    return {lambda, x1 + quadraticWeight * piece.x1Quadratic, x2 + quadraticWeight * piece.x2Quadratic};
}
// Whether the piece needs the full estimate (estimateSwept, estimateModulus): the voxel loop's longer path.
inline bool needsFullEstimate(const RodPiece& p) {
  return p.x1Across1 != 0.0 || p.x1Across2 != 0.0 || p.x2Across1 != 0.0 || p.x2Across2 != 0.0 || p.modulusCubic != 0.0 ||
         p.modulusAcross1 != 0.0 || p.modulusAcross2 != 0.0;
}
// E at a point of the piece before the clamp (RodPiece). A `Piece` may hold modulusRise = modulusEnd -
// modulusBegin ready (voxel::detail::SweptLanes).
template <bool Full = true, typename T, typename Piece>
inline T modulusBlend(const Piece& piece, const SweptEstimateOf<T>& at) {
  const auto rise = [&] {
    if constexpr (requires { piece.modulusRise; }) return piece.modulusRise;
    else return piece.modulusEnd - piece.modulusBegin;
  }();
  const T lambda = at.lambda;
  if constexpr (Full)
    return piece.modulusBegin + lambda * rise +
           lambda * (1.0 - lambda) *
               (piece.modulusQuadratic + (piece.modulusCubic * (lambda - 0.5) + (piece.modulusAcross1 * at.x1 + piece.modulusAcross2 * at.x2)));
  else
    return piece.modulusBegin + lambda * rise + lambda * (1.0 - lambda) * piece.modulusQuadratic;
}
// The blend held within the piece's E bounds. A `Piece` may hold them in lanes ready (modulusFloor =
// T{} + modulusLow, modulusCeiling = T{} + modulusHigh): the same values, so the same bits, where
// computing them for every quad cost vector instructions.
template <bool Full = true, typename T, typename Piece>
inline T estimateModulus(const Piece& piece, const SweptEstimateOf<T>& at) {
  const T e = modulusBlend<Full>(piece, at);
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
