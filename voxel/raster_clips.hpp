// Internal to voxel/ (the rasterizer's translation units): the block layout, the four-lane vectors
// of the swept and cap loops, and the clips that bound a piece's voxels row by row (planes, the
// piece's axis cylinder). Nothing here is part of the stage's interface.
#pragma once

// The four-lane vectors (Double4 and friends, also through rod_pieces.hpp's templates) pass between
// inline functions of the rasterizer only; GCC's note that their by-value ABI differs without AVX
// concerns no interface anyone links to.
#pragma GCC diagnostic ignored "-Wpsabi"

#include "voxel/printer_grid.hpp"
#include "voxel/rasterize.hpp"
#include "voxel/rod_pieces.hpp"

#include <emmintrin.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace rodfab::voxel::detail {

inline constexpr int kLeafLog2 = 3;
inline constexpr int kLeafDim = 1 << kLeafLog2;
inline constexpr int kLeafVoxels = kLeafDim * kLeafDim * kLeafDim;
// Work is binned by blocks of 8 leaves along x (64 x 8 x 8 voxels): rows along x then run up to 64
// voxels per setup instead of 8 (a 1.2 mm rod spans 28 voxels in x, so fewer rows are cut by a block
// edge than with 32), and a block holds 96 KiB of candidates (within the L2 cache's share).
inline constexpr int kBlockLeavesLog2 = 3;
inline constexpr int kBlockLeaves = 1 << kBlockLeavesLog2;
inline constexpr int kBlockXLog2 = kLeafLog2 + kBlockLeavesLog2;
inline constexpr int kBlockX = 1 << kBlockXLog2;
inline constexpr int kBlockVoxels = kBlockLeaves * kLeafVoxels;
inline constexpr int kPackedAxisBits = 21;  // per axis in a packed block coordinate: PrinterGrid caps dims at 2^24 voxels

// Within this distance (mm) beyond an end plane Rod::classify still uses the section (its own plane
// tolerance is 1e-9 (1 + bounding radius)); such voxel centres go to the exact test.
inline double capPlaneTolerance(double boundingRadius) { return 1e-7 * (1.0 + boundingRadius); }

// Four doubles (GCC vector extension; two SSE2 registers in the baseline build, one AVX register in
// the AVX2 clone of the swept loop): the swept estimate for four voxels at once. Lane by lane the same
// IEEE operations as the scalar expressions, so the same bits.
typedef double Double4 __attribute__((vector_size(32)));
typedef float Float4 __attribute__((vector_size(16)));
typedef std::int64_t Mask4 __attribute__((vector_size(32)));  // a comparison of Double4s: -1 true, 0 false
typedef std::int32_t Int4 __attribute__((vector_size(16)));
typedef std::uint64_t Owner4 __attribute__((vector_size(32)));  // a slot's owner (rod, piece), four times
// Every function taking or returning a 32-byte vector (Double4, Mask4, Owner4) that the target_clones
// loops (sweep, cap) call is always_inline: the avx2 clone passes such a vector in a ymm register, the
// baseline ABI in memory, and an out-of-line copy (an inline function is one comdat copy, compiled for
// the baseline) then reads the wrong place: at -O2 (RelWithDebInfo, the sanitizer build) GCC kept
// LeafBuilder::addFourCapCandidates out of line and the avx2 cap wrote garbage moduli (0, NaN, 1e38).
// tests/check_vector_abi.sh checks the built library for such out-of-line functions.

// |v| lane by lane, exactly as std::abs (clears the sign bit).
[[gnu::always_inline]] inline Double4 absolute(Double4 v) {
  return reinterpret_cast<Double4>(reinterpret_cast<Mask4>(v) & std::numeric_limits<std::int64_t>::max());
}

// sqrt lane by lane (correctly rounded, as std::sqrt), two lanes per SSE2 instruction.
[[gnu::always_inline]] inline Double4 squareRoot(Double4 v) {
  const __m128d low = _mm_sqrt_pd(_mm_set_pd(v[1], v[0])), high = _mm_sqrt_pd(_mm_set_pd(v[3], v[2]));
  return Double4{low[0], low[1], high[0], high[1]};
}

// The lanes of a comparison as bits 0 to 3 (two SSE2 movemasks).
[[gnu::always_inline]] inline unsigned laneBits(Mask4 m) {
  const Double4 d = reinterpret_cast<Double4>(m);
  const __m128d low = __builtin_shufflevector(d, d, 0, 1), high = __builtin_shufflevector(d, d, 2, 3);
  return static_cast<unsigned>(_mm_movemask_pd(low) | (_mm_movemask_pd(high) << 2));
}

// A value in all four lanes.
[[gnu::always_inline]] inline Double4 broadcast(double v) { return Double4{v, v, v, v}; }

// An affine function's c and gy in all four lanes (with its gz), for LayerRows: set once per piece.
struct RowLanes {
  RowLanes() = default;
  [[gnu::always_inline]] explicit RowLanes(const AffineInIndex& f) : c(broadcast(f.c)), gy(broadcast(f.gy)), gz(f.gz) {}
  Double4 c, gy;
  double gz = 0.0;
};

// A swept piece's coefficients for the voxel loop, copied out of the piece into all four lanes once
// per piece (the builder holds them, see LeafBuilder::swept_): held as scalars, they were broadcast
// (and spilled) again for every row, some 35 instructions a row, and the planes' and frame
// coordinates' rows for every layer, some 36 instructions a layer. The same values, so estimateSwept
// and estimateModulus give the same bits. With them the section's inverse half-sizes, the
// sure-inside threshold on the gauge (ShellThresholds::sureInsideBelow) and what a quad's slots store
// besides its values.
struct SweptLanes {
  SweptLanes() = default;
  // Inline, so that sweep stores the lanes straight into its member (out of line, the lanes went to a
  // temporary and were then copied, 512 bytes by `rep movsq`, once per piece and block).
  [[gnu::always_inline]] SweptLanes(const detail::RodPiece& p, const AffineInIndex& planeA, const AffineInIndex& planeB,
                                    double inverseHalfWidth, double inverseHalfHeight, double sureInside, float errorBound,
                                    std::uint64_t owner)
      : gxA(broadcast(planeA.gx)), gxB(broadcast(planeB.gx)), gx1Begin(broadcast(p.x1Begin.gx)), gx2Begin(broadcast(p.x2Begin.gx)),
        gx1End(broadcast(p.x1End.gx)), gx2End(broadcast(p.x2End.gx)), x1Quadratic(broadcast(p.x1Quadratic)),
        x2Quadratic(broadcast(p.x2Quadratic)), x1Across1(broadcast(p.x1Across1)), x1Across2(broadcast(p.x1Across2)),
        x2Across1(broadcast(p.x2Across1)), x2Across2(broadcast(p.x2Across2)), modulusBegin(broadcast(p.modulusBegin)),
        modulusQuadratic(broadcast(p.modulusQuadratic)), modulusCubic(broadcast(p.modulusCubic)), modulusAcross1(broadcast(p.modulusAcross1)),
        modulusAcross2(broadcast(p.modulusAcross2)), modulusRise(broadcast(p.modulusEnd) - modulusBegin),
        modulusFloor(Double4{} + broadcast(p.modulusLow)), modulusCeiling(Double4{} + broadcast(p.modulusHigh)),
        iA(broadcast(inverseHalfWidth)), iB(broadcast(inverseHalfHeight)), sureInsideBelow(broadcast(sureInside)),
        planeARows(planeA), planeBRows(planeB), x1BeginRows(p.x1Begin), x2BeginRows(p.x2Begin), x1EndRows(p.x1End),
        x2EndRows(p.x2End), errorBounds(Float4{} + errorBound), owners(Owner4{} + owner) {}
  Double4 gxA, gxB, gx1Begin, gx2Begin, gx1End, gx2End;
  Double4 x1Quadratic, x2Quadratic, x1Across1, x1Across2, x2Across1, x2Across2;  // as in RodPiece
  Double4 modulusBegin, modulusQuadratic, modulusCubic, modulusAcross1, modulusAcross2;
  Double4 modulusRise, modulusFloor, modulusCeiling;  // estimateModulus's per-piece parts (see there)
  Double4 iA, iB, sureInsideBelow;  // RodPieces::inverseHalfWidth, inverseHalfHeight; ShellThresholds::sureInsideBelow
  RowLanes planeARows, planeBRows, x1BeginRows, x2BeginRows, x1EndRows, x2EndRows;  // for LayerRows
  Float4 errorBounds;  // what a quad's slots store: the piece's error bound (rounded up to float) and owner
  Owner4 owners;
};

// std::max and std::min lane by lane: (a < b) ? b : a and (b < a) ? b : a.
[[gnu::always_inline]] inline Double4 largerOf(Double4 a, Double4 b) { return a < b ? b : a; }
[[gnu::always_inline]] inline Double4 smallerOf(Double4 a, Double4 b) { return b < a ? b : a; }

// AffineInIndex::row for the rows of one layer k, four rows j[0..3] at a time, lane by lane the same
// expression (c + gy j) + gz k. The coefficients in lanes come from the piece's RowLanes and gz k is set
// once per layer: read from the piece for every four rows, GCC loaded them again each time (the slots
// the rows' voxels are stored to are doubles too, so they might have changed the piece).
struct LayerRows {
  [[gnu::always_inline]] LayerRows(const RowLanes& f, int k) : f_(f), gzk(broadcast(f.gz * k)) {}
  [[gnu::always_inline]] Double4 at(Double4 j) const { return (f_.c + f_.gy * j) + gzk; }
  const RowLanes& f_;
  Double4 gzk;
};

// A double error bound as a float that is not smaller.
inline float roundedUpToFloat(double bound) {
  const float f = static_cast<float>(bound);
  return double(f) >= bound ? f : std::nextafter(f, std::numeric_limits<float>::infinity());
}

inline int clampToInt(double v) { return static_cast<int>(std::clamp(v, -2.0e9, 2.0e9)); }
// clampToInt(std::ceil(v)) and clampToInt(std::floor(v)) lane by lane, with vector instructions only
// (SSE2 has no rounding one; lane by lane, std::ceil and std::floor cost some 40 instructions per four
// rows). The clamp is std::clamp's min(max(v, lo), hi) with std::max and std::min's comparisons; its
// bounds are integers, so clamping first gives the same value. The clamped value's truncation t
// (cvttpd2dq, as cvttsd2si for each lane) is then its ceiling (floor), or one below (above) it where
// t < v (t > v). A NaN lane gives INT_MIN either way.
[[gnu::always_inline]] inline Double4 clampLanes(Double4 v) {
  const Double4 low = broadcast(-2.0e9), high = broadcast(2.0e9);
  const Double4 atLeast = v < low ? low : v;
  return high < atLeast ? high : atLeast;
}
[[gnu::always_inline]] inline Double4 truncatedLanes(Double4 clamped) { return __builtin_convertvector(__builtin_convertvector(clamped, Int4), Double4); }
[[gnu::always_inline]] inline Int4 ceilToInts(Double4 v) {
  const Double4 clamped = clampLanes(v), t = truncatedLanes(clamped);
  return __builtin_convertvector(t < clamped ? t + 1.0 : t, Int4);  // integers below 2^31: exact
}
[[gnu::always_inline]] inline Int4 floorToInts(Double4 v) {
  const Double4 clamped = clampLanes(v), t = truncatedLanes(clamped);
  return __builtin_convertvector(t > clamped ? t - 1.0 : t, Int4);
}

// The swept loop's thresholds on `test` (see sweep): gauges below 1 - bound are inside for sure, above
// 1 + bound outside for sure; between them (the tolerance shell around the section boundary) the exact
// test decides. Squared for round sections, whose test is the gauge squared.
struct ShellThresholds {
  ShellThresholds(double errorBound, bool rectangle) {
    const bool bounded = std::isfinite(errorBound) && errorBound < 1.0;
    const double inner = bounded ? 1.0 - errorBound : -1.0,
                 outer = bounded ? 1.0 + errorBound : std::numeric_limits<double>::infinity();
    const double innerSq = inner > 0.0 ? inner * inner : -1.0, outerSq = outer * outer;
    sureInsideBelow = rectangle ? inner : innerSq;
    sureOutsideAbove = rectangle ? outer : outerSq;
  }
  double sureInsideBelow, sureOutsideAbove;
};

// Voxel indices are below 2^24, so a root computed in double is off by far less than this; the
// clips keep that margin and the callers still test every voxel they are left with.
inline constexpr double kClipMargin = 1e-6;

// Depths closer than this are a tie (see rasterize.hpp): far below any approximation error bound, far above
// the round-off in a depth.
inline constexpr double kTieTolerance = kDepthTieTolerance;

// Restricts [lo, hi] to the i with base + slope * i >= 0 (conservatively). Returns false when
// nothing is left.
[[gnu::always_inline]] inline bool clipHalfLine(double base, double slope, int& lo, int& hi) {
  if (slope > 0.0) {
    lo = std::max(lo, clampToInt(std::ceil(-base / slope - kClipMargin)));
  } else if (slope < 0.0) {
    hi = std::min(hi, clampToInt(std::floor(-base / slope + kClipMargin)));
  } else if (base < 0.0) {
    return false;
  }
  return lo <= hi;
}

// A slope and its reciprocal, for clipping every row of a piece with a multiplication rather than a
// division: within the grid (|-base / slope| < 2^24) the product is off by under 1e-8 voxel, far
// inside kClipMargin. A reciprocal that overflows is replaced by 0, which clips nothing.
struct Slope {
  double slope, inverse;
  explicit Slope(double s) : slope(s), inverse(std::isfinite(1.0 / s) ? 1.0 / s : 0.0) {}
  [[gnu::always_inline]] bool clip(double base, int& lo, int& hi) const {
    if (slope > 0.0) lo = std::max(lo, clampToInt(std::ceil(-base * inverse - kClipMargin)));
    else if (slope < 0.0) hi = std::min(hi, clampToInt(std::floor(-base * inverse + kClipMargin)));
    else if (base < 0.0) return false;
    return lo <= hi;
  }
  // The same bound on the real line, for RowBounds; false when no i qualifies.
  [[gnu::always_inline]] bool bound(double base, double& lo, double& hi) const {
    if (slope > 0.0) lo = std::max(lo, -base * inverse);
    else if (slope < 0.0) hi = std::min(hi, -base * inverse);
    else if (base < 0.0) return false;
    return true;
  }
  // `bound` for four rows at once, lane by lane the same expressions (the same bits); `missed` marks
  // the rows where no i qualifies.
  [[gnu::always_inline]] void bound(Double4 base, Double4& lo, Double4& hi, Mask4& missed) const {
    if (slope > 0.0) lo = largerOf(lo, -base * inverse);
    else if (slope < 0.0) hi = smallerOf(hi, -base * inverse);
    else missed |= base < 0.0;
  }
};

// Bounds on a row's i, gathered as reals and rounded once: ceil(max(x) - margin) is the largest of
// the ceil(x - margin) (rounding, ceil and the clamp are monotone), so one ceil, clamp and conversion
// per side give the same range as rounding every bound.
struct RowBounds {
  double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
  [[gnu::always_inline]] bool round(int& first, int& last) const {
    first = std::max(first, clampToInt(std::ceil(lo - kClipMargin)));
    last = std::min(last, clampToInt(std::floor(hi + kClipMargin)));
    return first <= last;
  }
};

// The infinite cylinder of radius `reach` around a piece's axis, restricted to rows. With w the offset
// of a voxel centre from the axis point, the centre is inside where |w|^2 - (w.e)^2 <= reach^2: along a
// row (steps of vx in x) alpha i^2 + 2 beta i + gamma <= 0, where beta is linear and gamma quadratic in
// j. `layer` sets up the coefficients of one layer (once), `row` solves one row's quadratic with a
// square root and no division.
class AxisCylinder {
public:
  AxisCylinder(const PrinterGrid& grid, const RodPiece& piece)
      : grid_(grid), piece_(piece), e_(piece.axisDirection), vx_(grid.voxelSize.x()), vy_(grid.voxelSize.y()),
        alpha_(vx_ * vx_ * (1.0 - e_.x() * e_.x())), alongX_(alpha_ <= 1e-9 * vx_ * vx_),
        inverseAlpha_(alongX_ ? 0.0 : 1.0 / alpha_), b1_(-vx_ * vy_ * e_.y() * e_.x()),
        g2_(vy_ * vy_ * (1.0 - e_.y() * e_.y())), A_(b1_ * b1_ - alpha_ * g2_), inLayer_(!(A_ < -1e-12 * vx_ * vx_ * vy_ * vy_)),
        inverse2A_(inLayer_ ? 0.0 : 0.5 / A_) {}

  // Layer k, rows counted from j0: narrows [lo, hi] to the rows that meet the cylinder (the
  // discriminant of the row's quadratic, a quadratic in j whose leading coefficient works out to
  // -(vx vy e_z)^2, is >= 0 on one interval). With the axis along x every row is kept and `row`
  // clips nothing, as with the axis (nearly) in the layer.
  [[gnu::always_inline]] bool layer(int k, int j0, int& lo, int& hi) {
    j0_ = j0;
    if (alongX_) return lo <= hi;
    const geometry::Vec3 w(grid_.origin.x() - piece_.axisPoint.x(), grid_.origin.y() + j0 * vy_ - piece_.axisPoint.y(),
                           grid_.origin.z() + k * grid_.voxelSize.z() - piece_.axisPoint.z());
    const double we = w.dot(e_);
    b0_ = vx_ * (w.x() - we * e_.x());
    g0_ = w.squaredNorm() - we * we - piece_.reach * piece_.reach;
    g1_ = 2.0 * vy_ * (w.y() - we * e_.y());
    if (inLayer_) return lo <= hi;  // axis (nearly) in the layer: no bound in j
    const double B = 2.0 * b0_ * b1_ - alpha_ * g1_, C = b0_ * b0_ - alpha_ * g0_;
    const double disc = B * B - 4.0 * A_ * C;
    if (disc < 0.0) return false;
    const double root = std::sqrt(disc);
    // A < 0: D(j) >= 0 between the roots (multiplying by 1 / 2A is as conservative as a division, see Slope).
    lo = std::max(lo, j0 + clampToInt(std::ceil((-B + root) * inverse2A_ - kClipMargin)));
    hi = std::min(hi, j0 + clampToInt(std::floor((-B - root) * inverse2A_ + kClipMargin)));
    return lo <= hi;
  }

  // Row j of the current layer: narrows the bounds to the voxels inside the cylinder.
  [[gnu::always_inline]] bool row(int j, RowBounds& b) const {
    if (alongX_) return true;  // row (nearly) parallel to the axis: the other clips bound it
    const double dj = j - j0_;
    const double beta = b0_ + b1_ * dj, gamma = g0_ + (g1_ + g2_ * dj) * dj;
    const double disc = beta * beta - alpha_ * gamma;
    if (disc < 0.0) return false;
    const double root = std::sqrt(disc);
    b.lo = std::max(b.lo, (-beta - root) * inverseAlpha_);
    b.hi = std::min(b.hi, (-beta + root) * inverseAlpha_);
    return true;
  }

  // Rows j .. j + 3 of the current layer at once: lane by lane the expressions of `row` (the same
  // bits, one vector square root for four rows); `missed` marks the rows that miss the cylinder.
  [[gnu::always_inline]] void rows(int j, Double4& lo, Double4& hi, Mask4& missed) const {
    if (alongX_) return;
    const Double4 dj = double(j - j0_) + Double4{0.0, 1.0, 2.0, 3.0};
    const Double4 beta = b0_ + b1_ * dj, gamma = g0_ + (g1_ + g2_ * dj) * dj;
    const Double4 disc = beta * beta - alpha_ * gamma;
    missed |= disc < 0.0;
    const Double4 root = squareRoot(disc);  // not a number where missed; those lanes go unused
    lo = largerOf(lo, (-beta - root) * inverseAlpha_);
    hi = smallerOf(hi, (-beta + root) * inverseAlpha_);
  }

private:
  const PrinterGrid& grid_;
  const RodPiece& piece_;
  const geometry::Vec3& e_;
  double vx_, vy_, alpha_;
  bool alongX_;
  double inverseAlpha_;
  double b1_, g2_, A_;  // the parts of the coefficients that do not depend on the layer
  bool inLayer_;
  double inverse2A_;
  int j0_ = 0;
  double b0_ = 0.0, g0_ = 0.0, g1_ = 0.0;
};

// The row bounds of four rows at once (see RowBounds), and the rows with no voxel (`missed`).
struct FourRowBounds {
  // RowBounds::round for the four rows at once, from [boxLo, boxHi]: lane by lane the same integers
  // (ceilToInts, floorToInts), so each row gets the range round gives it. Rows with no voxel (missed,
  // or first > last) are marked in `empty`.
  [[gnu::always_inline]] void round(int boxLo, int boxHi, Int4& first, Int4& last, Mask4& empty) const {
    const Int4 upInt = ceilToInts(lo - kClipMargin), downInt = floorToInts(hi + kClipMargin);
    first = upInt > boxLo ? upInt : Int4{} + boxLo;  // std::max(boxLo, clampToInt(...)), lane by lane
    last = downInt < boxHi ? downInt : Int4{} + boxHi;
    empty = missed | __builtin_convertvector(first > last, Mask4);
  }
  Double4 lo = broadcast(-std::numeric_limits<double>::infinity()), hi = broadcast(std::numeric_limits<double>::infinity());
  Mask4 missed{};
};

// Four rows j .. j + 3 (jv: j to j + 3 as doubles) of a layer set up at once for a swept piece between
// planes a and b (their rows in the layer): the planes' rows, and the row bounds of the slab (slopes) and the axis cylinder with one vector square root,
// lane by lane the scalar clips' expressions (so the same bits).
struct FourRows : FourRowBounds {
  [[gnu::always_inline]] FourRows(const LayerRows& planeA, const LayerRows& planeB, const Slope& slopeA, const Slope& slopeB,
                                  const AxisCylinder& cylinder, int j, Double4 jv) {
    a = planeA.at(jv);
    b = planeB.at(jv);
    slopeA.bound(a, lo, hi, missed);
    slopeB.bound(-b, lo, hi, missed);
    cylinder.rows(j, lo, hi, missed);
  }
  Double4 a, b;
};

}  // namespace rodfab::voxel::detail
