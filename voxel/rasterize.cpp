// The four-lane vectors of the swept loop (Double4 and friends, also through rod_pieces.hpp's templates)
// pass between inline functions of this file only; GCC's note that their by-value ABI differs without
// AVX concerns no interface anyone links to.
#pragma GCC diagnostic ignored "-Wpsabi"

#include "voxel/rasterize.hpp"

#include "voxel/rod_pieces.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include <emmintrin.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>

namespace rodfab::voxel {

using detail::AffineInIndex;
using detail::RodPiece;
using detail::RodPieces;
using LeafT = openvdb::FloatTree::LeafNodeType;

namespace {

constexpr int kLeafLog2 = 3;
constexpr int kLeafDim = 1 << kLeafLog2;
constexpr int kLeafVoxels = kLeafDim * kLeafDim * kLeafDim;
// Work is binned by blocks of 8 leaves along x (64 x 8 x 8 voxels): rows along x then run up to 64
// voxels per setup instead of 8 (a 1.2 mm rod spans 28 voxels in x, so fewer rows are cut by a block
// edge than with 32), and a block holds 96 KiB of candidates (within the L2 cache's share).
constexpr int kBlockLeavesLog2 = 3;
constexpr int kBlockLeaves = 1 << kBlockLeavesLog2;
constexpr int kBlockXLog2 = kLeafLog2 + kBlockLeavesLog2;
constexpr int kBlockX = 1 << kBlockXLog2;
constexpr int kBlockVoxels = kBlockLeaves * kLeafVoxels;
constexpr int kPackedAxisBits = 21;  // per axis in a packed block coordinate: PrinterGrid caps dims at 2^24 voxels

// Within this distance (mm) beyond an end plane Rod::classify still uses the section (its own plane
// tolerance is 1e-9 (1 + bounding radius)); such voxel centres go to the exact test.
double capPlaneTolerance(double boundingRadius) { return 1e-7 * (1.0 + boundingRadius); }

// One rod as a candidate for a voxel, as the exact test and the cold paths of the overlap rule see it.
struct Candidate {
  double depth = -std::numeric_limits<double>::infinity();
  float errorBound = 0.0f;  // bound on |depth - exact depth|, rounded up; 0 when the exact test computed it
  float value = 0.0f;
  int rod = -1;       // -1: outside (the exact test found the centre outside the rod)
  int piece = -1;
  bool inside() const { return rod >= 0; }
};

// Four doubles (GCC vector extension; two SSE2 registers in the baseline build, one AVX register in
// the AVX2 clone of the swept loop): the swept estimate for four voxels at once. Lane by lane the same
// IEEE operations as the scalar expressions, so the same bits.
typedef double Double4 __attribute__((vector_size(32)));
typedef float Float4 __attribute__((vector_size(16)));
typedef std::int64_t Mask4 __attribute__((vector_size(32)));  // a comparison of Double4s: -1 true, 0 false

// |v| lane by lane, exactly as std::abs (clears the sign bit).
inline Double4 absolute(Double4 v) {
  return reinterpret_cast<Double4>(reinterpret_cast<Mask4>(v) & std::numeric_limits<std::int64_t>::max());
}

// sqrt lane by lane (correctly rounded, as std::sqrt), two lanes per SSE2 instruction.
inline Double4 squareRoot(Double4 v) {
  const __m128d low = _mm_sqrt_pd(_mm_set_pd(v[1], v[0])), high = _mm_sqrt_pd(_mm_set_pd(v[3], v[2]));
  return Double4{low[0], low[1], high[0], high[1]};
}

// A swept piece's coefficients for the voxel loop, copied out of the piece (see sweep): the same
// values, so estimateSwept and estimateModulus give the same bits.
struct SweptLanes {
  SweptLanes(const detail::RodPiece& p, double planeAgx, double planeBgx)
      : gxA(planeAgx), gxB(planeBgx), gx1Begin(p.x1Begin.gx), gx2Begin(p.x2Begin.gx), gx1End(p.x1End.gx), gx2End(p.x2End.gx),
        x1Quadratic(p.x1Quadratic), x2Quadratic(p.x2Quadratic), modulusBegin(p.modulusBegin), modulusEnd(p.modulusEnd),
        modulusQuadratic(p.modulusQuadratic), modulusLow(p.modulusLow), modulusHigh(p.modulusHigh) {}
  double gxA, gxB, gx1Begin, gx2Begin, gx1End, gx2End;
  double x1Quadratic, x2Quadratic, modulusBegin, modulusEnd, modulusQuadratic, modulusLow, modulusHigh;  // as in RodPiece
};

// A double error bound as a float that is not smaller.
float roundedUpToFloat(double bound) {
  const float f = static_cast<float>(bound);
  return double(f) >= bound ? f : std::nextafter(f, std::numeric_limits<float>::infinity());
}

// A piece reaching a block. Sorted by (block, rod, piece), a total order: every voxel sees its pieces
// in the same order whatever the thread count or band.
struct Entry {
  std::uint64_t block;
  std::uint32_t rod, piece;
  bool operator<(const Entry& o) const {
    if (block != o.block) return block < o.block;
    if (rod != o.rod) return rod < o.rod;
    return piece < o.piece;
  }
};

// Block coordinates packed into one sort key, z-major, so the blocks of a band of layers are contiguous.
std::uint64_t packBlock(int bi, int bj, int bk) {
  return (std::uint64_t(bk) << (2 * kPackedAxisBits)) | (std::uint64_t(bj) << kPackedAxisBits) | std::uint64_t(bi);
}
openvdb::Coord blockOrigin(std::uint64_t packed) {
  const std::uint64_t mask = (std::uint64_t(1) << kPackedAxisBits) - 1;
  return openvdb::Coord(int(packed & mask) << kBlockXLog2, int((packed >> kPackedAxisBits) & mask) << kLeafLog2,
                        int(packed >> (2 * kPackedAxisBits)) << kLeafLog2);
}

int clampToInt(double v) { return static_cast<int>(std::clamp(v, -2.0e9, 2.0e9)); }

// Voxel indices are below 2^24, so a root computed in double is off by far less than this; the
// clips keep that margin and the callers still test every voxel they are left with.
constexpr double kClipMargin = 1e-6;

// Depths closer than this are a tie (see rasterize.hpp): far below any approximation error bound, far above
// the round-off in a depth.
constexpr double kTieTolerance = kDepthTieTolerance;

// Restricts [lo, hi] to the i with base + slope * i >= 0 (conservatively). Returns false when
// nothing is left.
bool clipHalfLine(double base, double slope, int& lo, int& hi) {
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
  bool layer(int k, int j0, int& lo, int& hi) {
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

class LeafBuilder {
public:
  LeafBuilder(const geometry::RodStructure& structure, const std::vector<RodPieces>& rods, const PrinterGrid& grid,
              const std::function<bool()>& interrupted)
      : voxelsPerRod(structure.rods.size(), 0), structure_(structure), rods_(rods), grid_(grid), interrupted_(interrupted),
        deferredDepth_(structure.rods.size()) {
    for (std::size_t r = 0; r < deferredDepth_.size(); ++r)
      deferredDepth_[r] = structure.rods[r].section().shape != geometry::SectionShape::Rectangle;
  }

  std::uint64_t exactEvaluations = 0;
  std::vector<std::uint64_t> voxelsPerRod;  // filled slots won, per rod, over every block built

  // Slots hold a candidate of a rod the voxel lies in exactly where their bit in `filled_` is set:
  // clearing a block costs 512 bytes, not the 96 KiB of slots.
  void clear() {
    filled_.fill(0);
    memoRod_ = -1;
  }
  // Writes the block's filled slots into leaves; leaf(l) creates the block's l-th leaf along x (its
  // values 0). Slots are row by row (see offset) and leaves column by column, so a leaf's value mask
  // is the transpose of `filled_`: word x of leaf l holds bit r = (y, z) for column i = 8 l + x, where
  // filled_ holds bit i of row r. Per leaf, each row's byte of `filled_` writes its eight values at
  // once (the slot's value where the bit is set, else the leaf's 0: the slots of an empty voxel hold
  // some earlier block's value, never an indeterminate one, see value_), and the mask words come
  // from the 64 row bytes by movemask, eight bits a row at a time.
  template <typename MakeLeaf>
  void emit(MakeLeaf&& leaf) const {
    std::uint64_t anyRow = 0;
    for (std::uint64_t w : filled_) anyRow |= w;
    for (int l = 0; l < kBlockLeaves; ++l) {
      if (((anyRow >> (l * kLeafDim)) & 0xffu) == 0) continue;
      LeafT& node = leaf(l);
      float* values = node.buffer().data();
      alignas(16) std::array<std::uint8_t, kRows> bytes;
      for (int r = 0; r < kRows; ++r) {
        const unsigned byte = static_cast<unsigned>(filled_[static_cast<std::size_t>(r)] >> (l * kLeafDim)) & 0xffu;
        bytes[static_cast<std::size_t>(r)] = static_cast<std::uint8_t>(byte);
        if (byte == 0) continue;
        const float* slots = &value_[static_cast<std::size_t>((r << kBlockXLog2) | (l * kLeafDim))];
        for (int x = 0; x < kLeafDim; ++x) values[(x << (2 * kLeafLog2)) | r] = (byte >> x) & 1u ? slots[x] : 0.0f;
      }
      for (int x = 0; x < kLeafDim; ++x) {
        // Bit x of every row byte to its top bit (a 64-bit shift moves no bit across a byte's top).
        const __m128i shift = _mm_cvtsi32_si128(kLeafDim - 1 - x);
        std::uint64_t column = 0;
        for (int q = 0; q < kRows / 16; ++q) {
          const __m128i v = _mm_load_si128(reinterpret_cast<const __m128i*>(&bytes[static_cast<std::size_t>(16 * q)]));
          column |= std::uint64_t(static_cast<std::uint16_t>(_mm_movemask_epi8(_mm_sll_epi64(v, shift)))) << (16 * q);
        }
        node.getValueMask().template getWord<std::uint64_t>(openvdb::Index(x)) = column;
      }
    }
  }

  void addPiece(int rod, int pieceIndex, const openvdb::CoordBBox& box) {
    const RodPiece& piece = rods_[rod].pieces[pieceIndex];
    if (piece.kind == RodPiece::Kind::Swept) sweep(rod, pieceIndex, piece, box);
    else if (piece.kind == RodPiece::Kind::Exact) exactRegion(rod, pieceIndex, piece, box);
    else cap(rod, pieceIndex, piece, box);
    if (interruptSeen_) throw Interrupted("rasterizer: interrupted");
  }

private:
  // Slot of voxel (i, j, k) in its block: row by row, the 64 voxels of a row (j, k) along x
  // contiguous, so the swept loop fills four neighbours with one vector store, and a voxel's bit of
  // `filled_` is bit i & (kBlockX - 1) of the row's word. Rows are numbered (y, z) as a leaf numbers
  // the voxels of one x, which makes emit a transpose.
  static int offset(int i, int j, int k) {
    return (rowOf(j, k) << kBlockXLog2) | (i & (kBlockX - 1));
  }
  static int rowOf(int j, int k) { return ((j & (kLeafDim - 1)) << kLeafLog2) | (k & (kLeafDim - 1)); }
  static std::uint64_t owner(int rod, int piece) { return (std::uint64_t(std::uint32_t(rod)) << 32) | std::uint32_t(piece); }
  Candidate exact(int rod, int pieceIndex, int i, int j, int k) {
    // The exact test is the one costly step per voxel (a Newton solve per nearby polyline segment):
    // the interrupter is polled between every 64 of them.
    // No throw here: sweep() is a target_clones function, and GCC 12 treats a call to one as unable to
    // throw, so an exception leaving it ended the process (std::terminate). The first poll that sees
    // the interrupt marks the builder; the rest of the piece is skipped and addPiece() throws.
    if (interrupted_ && ++exactEvaluations % 64 == 0 && interrupted_()) interruptSeen_ = true;
    if (!interrupted_) ++exactEvaluations;
    if (interruptSeen_) return {};
    const openvdb::Vec3d p = grid_.worldPoint(openvdb::Coord(i, j, k));
    const geometry::Rod& r = structure_.rods[rod];
    const geometry::RodHit hit = r.classify(geometry::Vec3(p.x(), p.y(), p.z()));
    if (!hit.inside) return {};
    return {hit.depth, 0.0f, static_cast<float>(r.modulus().value(hit.u)), rod, pieceIndex};
  }

  // A slot stores its depth encoded: the depth itself, except for approximate candidates of rods with
  // round sections (errorBound > 0 and deferredDepth_), where it stores the gauge squared, (1 - depth)^2:
  // the square root is only taken when another rod competes for the voxel, and it is the same
  // expression the depth always came from. Approximate candidates always have errorBound > 0
  // (normalizedRadiusErrorBound has a 1e-12 floor) and exact ones 0.
  double decodedDepth(double encodedDepth, float errorBound, int rod) const {
    return errorBound > 0.0f && deferredDepth_[static_cast<std::size_t>(rod)] ? 1.0 - std::sqrt(encodedDepth) : encodedDepth;
  }
  // Four neighbouring slots n .. n + 3 of one row (see offset), as four stores would fill them.
  void storeFour(int n, Double4 encodedDepth, Float4 value, float errorBound, std::uint64_t who) {
    std::memcpy(&encodedDepth_[static_cast<std::size_t>(n)], &encodedDepth, sizeof encodedDepth);
    std::memcpy(&value_[static_cast<std::size_t>(n)], &value, sizeof value);
    for (int l = 0; l < 4; ++l) {
      errorBound_[static_cast<std::size_t>(n + l)] = errorBound;
      owner_[static_cast<std::size_t>(n + l)] = who;
    }
  }
  void store(int n, double encodedDepth, float errorBound, float value, std::uint64_t who) {
    encodedDepth_[n] = encodedDepth;
    errorBound_[n] = errorBound;
    value_[n] = value;
    owner_[n] = who;
  }

  // An approximate candidate that is inside for sure (depth encoded as in decodedDepth). The common
  // case, an empty slot, is a plain store, and returns 1 for the caller to add to the rod's tally; a
  // filled one goes through the overlap rule.
  int addSurelyInside(int n, double encodedDepth, float errorBound, float value, int rod, int piece, int i, int j, int k) {
    std::uint64_t& word = filled_[n >> 6];
    const std::uint64_t bit = std::uint64_t(1) << (n & 63);
    if (!(word & bit)) {
      store(n, encodedDepth, errorBound, value, owner(rod, piece));
      word |= bit;
      return 1;
    }
    const bool round = deferredDepth_[static_cast<std::size_t>(rod)];
    if (clearOverlap(n, round ? encodedDepth : (1.0 - encodedDepth) * (1.0 - encodedDepth), encodedDepth, errorBound, value, rod, piece))
      return 0;
    const Candidate c{decodedDepth(encodedDepth, errorBound, rod), errorBound, value, rod, piece};
    if (!overlapWithoutExactTest(n, c, encodedDepth)) resolveOverlap(n, c, encodedDepth, i, j, k);
    return 0;
  }
  // The overlap rule's outcome without square roots, where it is clear. Both sides are ranked by their
  // gauge squared, g^2 = (1 - depth)^2 with g in [0, 1]: an approximate round-section slot stores it
  // (encoded depth), an exact or cap slot with a depth in [0, 1] gives it as (1 - depth)^2, and the
  // caller passes the candidate's (`gaugeSquared`, in [0, 1]). With both gauges in [0, 1],
  // |sqrt(a) - sqrt(b)| >= |a - b| / 2, so a difference of squares above 2 (bounds + tie tolerance),
  // plus 1e-12 for the round-off of the depths and squares (below 1e-15), means resolveOverlap finds no
  // near tie and lets the deeper one (the smaller g^2) win: the same outcome, with the same stores.
  // Returns false where resolveOverlap must decide (or the slot's gauge is not at hand: an approximate
  // rectangle, an exact depth outside [0, 1]).
  bool clearOverlap(int n, double gaugeSquared, double encodedDepth, float errorBound, float value, int rod, int piece) {
    const std::uint64_t slotOwner = owner_[static_cast<std::size_t>(n)];
    const int slotRod = static_cast<int>(slotOwner >> 32);
    const float slotBound = errorBound_[static_cast<std::size_t>(n)];
    const double slotEncoded = encodedDepth_[static_cast<std::size_t>(n)];
    double slotGaugeSquared;
    if (slotBound > 0.0f) {
      if (!deferredDepth_[static_cast<std::size_t>(slotRod)]) return false;
      slotGaugeSquared = slotEncoded;
    } else {
      if (!(slotEncoded >= 0.0 && slotEncoded <= 1.0)) return false;
      slotGaugeSquared = (1.0 - slotEncoded) * (1.0 - slotEncoded);
    }
    const double clear = 2.0 * (double(slotBound) + double(errorBound) + kTieTolerance) + 1e-12;
    if (gaugeSquared - slotGaugeSquared > clear) return true;  // the candidate is clearly shallower: the slot stays
    if (slotGaugeSquared - gaugeSquared > clear) {              // clearly deeper: it takes the slot
      replaceSlot(n, encodedDepth, errorBound, value, rod, piece, slotRod);
      return true;
    }
    return false;
  }
  // A round cap's candidate inside it for sure, gauge g < 1 (depth 1 - g, exact up to round-off within
  // the tie tolerance). At a node nearly all of a cap lies inside the rods around it, whose deeper
  // candidates already hold most of its slots: clearOverlap settles those without a square root.
  void addCapCandidate(int n, double g, float value, int rod, int piece, int i, int j, int k) {
    std::uint64_t& word = filled_[static_cast<std::size_t>(n >> 6)];
    const std::uint64_t bit = std::uint64_t(1) << (n & 63);
    const double depth = 1.0 - g;
    if (!(word & bit)) {
      store(n, depth, 0.0f, value, owner(rod, piece));
      word |= bit;
      ++voxelsPerRod[static_cast<std::size_t>(rod)];
      return;
    }
    if (clearOverlap(n, g * g, depth, 0.0f, value, rod, piece)) return;
    const Candidate c{depth, 0.0f, value, rod, piece};
    if (!overlapWithoutExactTest(n, c, depth)) resolveOverlap(n, c, depth, i, j, k);
  }
  // Four neighbouring round-cap candidates of one row (slots n .. n + 3), inside for sure (gauges g < 1),
  // as addCapCandidate would take them one by one. Their common fate at a node, four filled slots each
  // clearly deeper than the cap, is settled with one comparison of four lanes: clearOverlap's
  // expressions lane by lane (the candidate's error bound is 0, so `clear` gets the same bits). Any
  // other case goes voxel by voxel.
  void addFourCapCandidates(int n, Double4 g, float value, int rod, int piece, int i, int j, int k) {
    if (((filled_[static_cast<std::size_t>(n >> 6)] >> (n & 63)) & 0xfu) == 0xfu) {
      Double4 slotEncoded;
      Float4 slotBoundFloat;
      std::memcpy(&slotEncoded, &encodedDepth_[static_cast<std::size_t>(n)], sizeof slotEncoded);
      std::memcpy(&slotBoundFloat, &errorBound_[static_cast<std::size_t>(n)], sizeof slotBoundFloat);
      const Double4 slotBound = __builtin_convertvector(slotBoundFloat, Double4);
      Mask4 roundSlot;
      for (int l = 0; l < 4; ++l)
        roundSlot[l] = deferredDepth_[static_cast<std::size_t>(owner_[static_cast<std::size_t>(n + l)] >> 32)] ? -1 : 0;
      const Mask4 approximate = slotBound > 0.0;
      // Where the slot's gauge is at hand (see clearOverlap); elsewhere the lane is not clear.
      const Mask4 atHand = (approximate & roundSlot) | (~approximate & (slotEncoded >= 0.0) & (slotEncoded <= 1.0));
      const Double4 slotGaugeSquared = approximate ? slotEncoded : (1.0 - slotEncoded) * (1.0 - slotEncoded);
      const Double4 clear = 2.0 * (slotBound + 0.0 + kTieTolerance) + 1e-12;
      const Mask4 slotStays = atHand & (g * g - slotGaugeSquared > clear);
      if (slotStays[0] & slotStays[1] & slotStays[2] & slotStays[3]) return;
    }
    for (int l = 0; l < 4; ++l) addCapCandidate(n + l, g[l], value, rod, piece, i + l, j, k);
  }
  // A candidate with its depth at hand (exact, or caps), possibly outside.
  void addCandidate(const Candidate& c, int n, int i, int j, int k) {
    std::uint64_t& word = filled_[n >> 6];
    const std::uint64_t bit = std::uint64_t(1) << (n & 63);
    if (!(word & bit)) {
      if (c.inside()) {
        store(n, c.depth, c.errorBound, c.value, owner(c.rod, c.piece));
        word |= bit;
        ++voxelsPerRod[static_cast<std::size_t>(c.rod)];
      }
      return;
    }
    if (!overlapWithoutExactTest(n, c, c.depth)) resolveOverlap(n, c, c.depth, i, j, k);
  }

  // The overlap rule, in one place: a candidate `gain` deeper than the slot's holder (sRod, sPiece)
  // takes the slot when it is deeper by more than kTieTolerance, or within it and of a lower rod (then
  // a lower piece). It decides which rod owns a voxel, so the job's bytes.
  [[gnu::always_inline]] static bool takesSlot(double gain, const Candidate& c, int sRod, int sPiece) {
    return gain > kTieTolerance || (gain >= -kTieTolerance && (c.rod < sRod || (c.rod == sRod && c.piece < sPiece)));
  }
  [[gnu::always_inline]] void replaceSlot(int n, double encodedDepth, float errorBound, float value, int rod, int piece, int oldRod) {
    store(n, encodedDepth, errorBound, value, owner(rod, piece));
    --voxelsPerRod[static_cast<std::size_t>(oldRod)];
    ++voxelsPerRod[static_cast<std::size_t>(rod)];
  }

  // resolveOverlap where it needs no exact test (no near tie involving an approximate depth): the same
  // expressions in the same order, so the same decision, inline and without a copy of the slot. At
  // the lattice's nodes this is nearly every overlap of a round cap with the rods around it.
  // Returns false where resolveOverlap must decide (a near tie).
  [[gnu::always_inline]] bool overlapWithoutExactTest(int n, const Candidate& c, double cEncodedDepth) {
    const std::uint64_t slotOwner = owner_[static_cast<std::size_t>(n)];
    const int sRod = static_cast<int>(slotOwner >> 32);
    const float sBound = errorBound_[static_cast<std::size_t>(n)];
    const double sDepth = decodedDepth(encodedDepth_[static_cast<std::size_t>(n)], sBound, sRod);
    if (std::abs(sDepth - c.depth) <= double(sBound) + double(c.errorBound) + kTieTolerance && (sBound > 0.0f || c.errorBound > 0.0f))
      return false;
    const double gain = c.depth - sDepth;
    const int sPiece = static_cast<int>(slotOwner & 0xffffffffu);
    if (c.inside() && takesSlot(gain, c, sRod, sPiece)) replaceSlot(n, cEncodedDepth, c.errorBound, c.value, c.rod, c.piece, sRod);
    return true;
  }

  // The overlap rule between filled slot n and candidate c (cEncodedDepth: c's depth as the slot would
  // store it). Near ties between approximate depths are settled on exact depths, so the winner is the
  // one the exact test would pick; depths within kTieTolerance are equal (lower rod wins), which spares
  // the exact test where round caps of rods meeting at a node coincide.
  [[gnu::noinline]] void resolveOverlap(int n, Candidate c, double cEncodedDepth, int i, int j, int k) {
    const int sRod = static_cast<int>(owner_[n] >> 32);
    Candidate s{decodedDepth(encodedDepth_[n], errorBound_[n], sRod), errorBound_[n], value_[n], sRod,
                static_cast<int>(owner_[n] & 0xffffffffu)};
    double sEncodedDepth = encodedDepth_[n];
    bool sChanged = false;
    if (std::abs(s.depth - c.depth) <= double(s.errorBound) + double(c.errorBound) + kTieTolerance &&
        (s.errorBound > 0.0f || c.errorBound > 0.0f)) {
      if (s.errorBound > 0.0f) {
        s = exact(s.rod, s.piece, i, j, k);
        sEncodedDepth = s.depth;
        sChanged = true;
      }
      if (c.errorBound > 0.0f) {
        c = exact(c.rod, c.piece, i, j, k);
        cEncodedDepth = c.depth;
      }
      if (!s.inside()) {  // the exact test overturned the approximate candidate
        --voxelsPerRod[static_cast<std::size_t>(sRod)];
        if (c.inside()) {
          store(n, cEncodedDepth, c.errorBound, c.value, owner(c.rod, c.piece));
          ++voxelsPerRod[static_cast<std::size_t>(c.rod)];
        } else {
          filled_[n >> 6] &= ~(std::uint64_t(1) << (n & 63));
        }
        return;
      }
    }
    const double gain = c.depth - s.depth;
    if (c.inside() && takesSlot(gain, c, s.rod, s.piece))
      replaceSlot(n, cEncodedDepth, c.errorBound, c.value, c.rod, c.piece, s.rod);
    else if (sChanged)
      store(n, sEncodedDepth, s.errorBound, s.value, owner(s.rod, s.piece));
  }

  // Cloned for AVX2 (four lanes in one register; AVX2 brings no FMA, so no multiply-add is fused and
  // the clone computes the bits the baseline does), chosen at load time.
  [[gnu::target_clones("avx2", "default")]] void sweep(int rod, int pieceIndex, const RodPiece& piece,
                                                       const openvdb::CoordBBox& box) {
    const RodPieces& rp = rods_[rod];
    const AffineInIndex& planeA = rp.planes[piece.plane];
    const AffineInIndex& planeB = rp.planes[piece.plane + 1];
    const double iA = rp.inverseHalfWidth, iB = rp.inverseHalfHeight;
    const bool rectangle = structure_.rods[rod].section().shape == geometry::SectionShape::Rectangle;
    const double errorBound = piece.normalizedRadiusErrorBound;
    const bool bounded = std::isfinite(errorBound) && errorBound < 1.0;
    const float floatErrorBound = roundedUpToFloat(errorBound);
    // Gauges below `inner` are inside for sure, above `outer` outside for sure; between them (the
    // tolerance shell around the section boundary) the exact test decides.
    const double inner = bounded ? 1.0 - errorBound : -1.0,
                 outer = bounded ? 1.0 + errorBound : std::numeric_limits<double>::infinity();
    const double innerSq = inner > 0.0 ? inner * inner : -1.0, outerSq = outer * outer;
    const double sureInsideBelow = rectangle ? inner : innerSq, sureOutsideAbove = rectangle ? outer : outerSq;
    const std::uint64_t who = owner(rod, pieceIndex);
    // Layers, then rows, that can hold a voxel of the slab a >= 0 > b within the box: the extremes of
    // the planes over the box's i (and j) bound them before any row is set up.
    const auto extreme = [](double g, int from, int to, bool largest) {
      return largest ? std::max(g * from, g * to) : std::min(g * from, g * to);
    };
    const openvdb::Coord &bmin = box.min(), &bmax = box.max();
    const double aMaxI = extreme(planeA.gx, bmin.x(), bmax.x(), true), bMinI = extreme(planeB.gx, bmin.x(), bmax.x(), false);
    int kLo = bmin.z(), kHi = bmax.z();
    if (!clipHalfLine(planeA.c + aMaxI + extreme(planeA.gy, bmin.y(), bmax.y(), true), planeA.gz, kLo, kHi) ||
        !clipHalfLine(-(planeB.c + bMinI + extreme(planeB.gy, bmin.y(), bmax.y(), false)), -planeB.gz, kLo, kHi))
      return;
    AxisCylinder cylinder(grid_, piece);
    const Slope slopeA(planeA.gx), slopeB(-planeB.gx), slopeAy(planeA.gy), slopeBy(-planeB.gy);
    const SweptLanes lanes(piece, planeA.gx, planeB.gx);
    for (int k = kLo; k <= kHi; ++k) {
      int jLo = bmin.y(), jHi = bmax.y();
      if (!slopeAy.clip(planeA.c + planeA.gz * k + aMaxI, jLo, jHi) || !slopeBy.clip(-(planeB.c + planeB.gz * k + bMinI), jLo, jHi) ||
          !cylinder.layer(k, bmin.y(), jLo, jHi))
        continue;
      for (int j = jLo; j <= jHi; ++j) {
        const double aRow = planeA.row(j, k), bRow = planeB.row(j, k);
        RowBounds bounds;
        int lo = bmin.x(), hi = bmax.x();
        if (!slopeA.bound(aRow, bounds.lo, bounds.hi) || !slopeB.bound(-bRow, bounds.lo, bounds.hi) ||
            !cylinder.row(j, bounds) || !bounds.round(lo, hi))
          continue;
        const double x1aRow = piece.x1Begin.row(j, k), x2aRow = piece.x2Begin.row(j, k);
        const double x1bRow = piece.x1End.row(j, k), x2bRow = piece.x2End.row(j, k);
        const int row = rowOf(j, k);
        std::uint64_t fresh = 0;
        // Four voxels at a time (see estimateSwept); the decisions per voxel. The coefficients are
        // locals (`lanes`), which the slot stores cannot alias, so they stay in registers. `test` is
        // what the tolerance shell is tested on: the gauge squared for round sections (encoded depth
        // as it is), the max-norm gauge for rectangles (encoded depth 1 - gauge).
        Double4 iv = double(lo) + Double4{0.0, 1.0, 2.0, 3.0};
        for (int i = lo; i <= hi; i += 4, iv += 4.0) {
          const Double4 av = aRow + lanes.gxA * iv, bv = bRow + lanes.gxB * iv;
          const detail::SweptEstimateOf<Double4> e =
              detail::estimateSwept(lanes, av, bv, x1aRow + lanes.gx1Begin * iv, x2aRow + lanes.gx2Begin * iv,
                                    x1bRow + lanes.gx1End * iv, x2bRow + lanes.gx2End * iv);
          Double4 test, encodedDepth;
          if (rectangle) {
            const Double4 g1 = absolute(e.x1) * iA, g2 = absolute(e.x2) * iB;
            test = g1 < g2 ? g2 : g1;  // std::max(g1, g2), lane by lane
            encodedDepth = 1.0 - test;
          } else {
            test = (e.x1 * iA) * (e.x1 * iA) + (e.x2 * iB) * (e.x2 * iB);
            encodedDepth = test;
          }
          const Double4 modulus = detail::estimateModulus(lanes, e.lambda);
          const Mask4 inSlab = (av >= 0.0) & (bv < 0.0);
          const Mask4 sure = inSlab & (test < sureInsideBelow);
          if (i + 3 <= hi && (sure[0] & sure[1] & sure[2] & sure[3])) {
            // The common case: four neighbours inside for sure; into empty slots with one store each.
            const int n = (row << kBlockXLog2) | (i & (kBlockX - 1));
            std::uint64_t& word = filled_[static_cast<std::size_t>(row)];
            if (((word >> (i & (kBlockX - 1))) & 0xfu) == 0) {
              storeFour(n, encodedDepth, __builtin_convertvector(modulus, Float4), floatErrorBound, who);
              word |= std::uint64_t(0xf) << (i & (kBlockX - 1));
              fresh += 4;
              continue;
            }
            for (int l = 0; l < 4; ++l)
              fresh += addSurelyInside(n + l, encodedDepth[l], floatErrorBound, static_cast<float>(modulus[l]), rod, pieceIndex,
                                       i + l, j, k);
            continue;
          }
          for (int l = 0; l < 4 && i + l <= hi; ++l) {
            if (!inSlab[l] || test[l] > sureOutsideAbove) continue;
            const int n = offset(i + l, j, k);
            if (sure[l])
              fresh += addSurelyInside(n, encodedDepth[l], floatErrorBound, static_cast<float>(modulus[l]), rod, pieceIndex,
                                       i + l, j, k);
            else
              addCandidate(exact(rod, pieceIndex, i + l, j, k), n, i + l, j, k);
          }
        }
        voxelsPerRod[static_cast<std::size_t>(rod)] += fresh;
      }
    }
  }

  // Every voxel of the piece's box within its reach of the chord, decided by the exact test; once per
  // voxel and rod in a block (exact pieces of a tight bend overlap, and the test already decides the
  // whole rod).
  void exactRegion(int rod, int pieceIndex, const RodPiece& piece, const openvdb::CoordBBox& box) {
    if (memoRod_ != rod) {
      memo_.fill(0);
      memoRod_ = rod;
    }
    AxisCylinder cylinder(grid_, piece);
    for (int k = box.min().z(); k <= box.max().z(); ++k) {
      int jLo = box.min().y(), jHi = box.max().y();
      if (!cylinder.layer(k, jLo, jLo, jHi)) continue;
      for (int j = jLo; j <= jHi; ++j) {
        RowBounds bounds;
        int lo = box.min().x(), hi = box.max().x();
        if (!cylinder.row(j, bounds) || !bounds.round(lo, hi)) continue;
        for (int i = lo; i <= hi; ++i) {
          const int n = offset(i, j, k);
          std::uint64_t& word = memo_[static_cast<std::size_t>(n >> 6)];
          const std::uint64_t bit = std::uint64_t(1) << (n & 63);
          if (word & bit) continue;
          word |= bit;
          addCandidate(exact(rod, pieceIndex, i, j, k), n, i, j, k);
        }
      }
    }
  }

  // The voxels of a cap's row that can do anything: those near the end plane (|a| <= nearPlane, sent
  // to the exact test) and, for round caps, those of the ball (|wx| <= sqrt(rest), wx = wxRow + gx i,
  // rest = radius^2 - wy^2 - wz^2 with the radius a little enlarged). Narrows `bounds` to the hull of
  // the two ranges, as conservatively as the other clips (see Slope); false when both are empty. Outside
  // them the loop would skip every voxel: the ball clip keeps the rows of an axis-aligned cap to its
  // half-ball instead of the half-cylinder (2/3 of the voxels) or the half-box (a third).
  [[gnu::always_inline]]
  static bool capRow(bool round, double aRow, double nearPlane, const Slope& rising, const Slope& falling, double wxRow,
                     double rest, const Slope& alongX, const Slope& againstX, RowBounds& bounds) {
    RowBounds near, ball;
    const bool anyNear = rising.bound(aRow + nearPlane, near.lo, near.hi) && falling.bound(nearPlane - aRow, near.lo, near.hi);
    bool anyBall = false;
    if (round && rest >= 0.0) {
      const double reach = std::sqrt(rest);
      anyBall = alongX.bound(wxRow + reach, ball.lo, ball.hi) && againstX.bound(reach - wxRow, ball.lo, ball.hi);
    }
    if (!anyNear && !anyBall) return false;
    const double lo = !anyBall ? near.lo : !anyNear ? ball.lo : std::min(near.lo, ball.lo);
    const double hi = !anyBall ? near.hi : !anyNear ? ball.hi : std::max(near.hi, ball.hi);
    bounds.lo = std::max(bounds.lo, lo);
    bounds.hi = std::min(bounds.hi, hi);
    return true;
  }

  // Cloned for AVX2 like sweep (no FMA there either, so the clones compute the same bits). Four voxels
  // a step: the plane value and the distance to the end point (with its square root) for four
  // neighbours at once, lane by lane the scalar expressions; then the decisions per voxel, in order.
  [[gnu::target_clones("avx2", "default")]] void cap(int rod, int pieceIndex, const RodPiece& piece,
                                                     const openvdb::CoordBBox& box) {
    const RodPieces& rp = rods_[rod];
    const geometry::Rod& r = structure_.rods[rod];
    const AffineInIndex& plane = rp.planes[piece.plane];
    const bool atEnd = piece.kind == RodPiece::Kind::EndCap, round = r.caps() == geometry::CapStyle::Round;
    // Beyond the plane: a >= 0 past the end, a < 0 before the beginning (the complements of the
    // swept pieces' conditions, evaluated identically).
    const double sign = atEnd ? 1.0 : -1.0;
    const double nearPlane = capPlaneTolerance(r.section().boundingRadius());
    const double invCap = rp.inverseCapRadius;
    constexpr double kCapRoundOff = 1e-9;  // round-off in the cap's distance, relative to its radius
    constexpr double kSurelyInside = 1.0 - kCapRoundOff, kSurelyOutside = 1.0 + kCapRoundOff;
    const float endModulus = piece.capModulus;
    AxisCylinder cylinder(grid_, piece);
    const Slope slope(sign * plane.gx), rising(plane.gx), falling(-plane.gx);
    const Slope alongX(piece.capOffset[0].gx), againstX(-piece.capOffset[0].gx);
    const double gxPlane = plane.gx, gxOffset = piece.capOffset[0].gx;
    // A little more than the largest |p - end point| the loop keeps (g <= 1 + kCapRoundOff, computed):
    // the margin (1e-9 of the radius) dwarfs the round-off of the distance and of the clip.
    const double ballRadiusSquared = ((1.0 + 2.0 * kCapRoundOff) / invCap) * ((1.0 + 2.0 * kCapRoundOff) / invCap);
    for (int k = box.min().z(); k <= box.max().z(); ++k) {
      int jLo = box.min().y(), jHi = box.max().y();
      if (!cylinder.layer(k, jLo, jLo, jHi)) continue;
      for (int j = jLo; j <= jHi; ++j) {
        const double aRow = plane.row(j, k), wxRow = piece.capOffset[0].row(j, k);
        const double wy = piece.capOffset[1].row(j, k), wz = piece.capOffset[2].row(j, k);
        const double wyz = wy * wy + wz * wz;
        RowBounds bounds;
        int lo = box.min().x(), hi = box.max().x();
        if (!slope.bound(sign * aRow, bounds.lo, bounds.hi) || !cylinder.row(j, bounds) ||
            !capRow(round, aRow, nearPlane, rising, falling, wxRow, ballRadiusSquared - wyz, alongX, againstX, bounds) ||
            !bounds.round(lo, hi))
          continue;
        Double4 iv = double(lo) + Double4{0.0, 1.0, 2.0, 3.0};
        for (int i = lo; i <= hi; i += 4, iv += 4.0) {
          const Double4 a = aRow + gxPlane * iv;
          const Mask4 beyond = atEnd ? (a >= 0.0) : (a < 0.0);
          const Mask4 near = absolute(a) <= nearPlane;
          Double4 g = Double4{} + std::numeric_limits<double>::infinity();  // flat caps: only the near-plane voxels
          if (round) {
            const Double4 wx = wxRow + gxOffset * iv;
            g = squareRoot(wx * wx + wyz) * invCap;
          }
          // Inside for sure; the depth's round-off (1e-9 of the radius at most) is within the tie
          // tolerance, so it counts as exact.
          const Mask4 sure = beyond & ~near & (g < kSurelyInside);
          if (i + 3 <= hi && (sure[0] & sure[1] & sure[2] & sure[3])) {
            const int n = offset(i, j, k);
            addFourCapCandidates(n, g, endModulus, rod, pieceIndex, i, j, k);
            continue;
          }
          for (int l = 0; l < 4 && i + l <= hi; ++l) {
            if (!beyond[l] || (!near[l] && g[l] > kSurelyOutside)) continue;
            if (sure[l]) addCapCandidate(offset(i + l, j, k), g[l], endModulus, rod, pieceIndex, i + l, j, k);
            else addCandidate(exact(rod, pieceIndex, i + l, j, k), offset(i + l, j, k), i + l, j, k);
          }
        }
      }
    }
  }

  const geometry::RodStructure& structure_;
  const std::vector<RodPieces>& rods_;
  const PrinterGrid& grid_;
  const std::function<bool()>& interrupted_;
  bool interruptSeen_ = false;  // exact() saw the interrupt: the block is abandoned (see exact)
  std::vector<unsigned char> deferredDepth_;  // per rod: round section (see decodedDepth)
  static constexpr int kRows = kLeafDim * kLeafDim;
  static constexpr int kWords = kBlockVoxels / 64;
  static_assert(kWords == kRows && kBlockX == 64, "a word of filled_ per row (y, z) of the block: bit x");
  // The slots, field by field (24 bytes a voxel), read only where `filled_` says they were written
  // (but for emit's reads of value_): left uninitialized, so that setting up a builder does not touch
  // their 80 KiB.
  std::array<double, kBlockVoxels> encodedDepth_;
  std::array<float, kBlockVoxels> errorBound_;
  std::array<float, kBlockVoxels> value_{};  // zeroed once: emit reads the slots of a row's empty voxels too
  std::array<std::uint64_t, kBlockVoxels> owner_;
  std::array<std::uint64_t, kWords> filled_{};
  std::array<std::uint64_t, kWords> memo_{};  // voxels of the block exactly tested for rod memoRod_
  int memoRod_ = -1;
};

// The pieces reaching each block of a band: entries sorted (see Entry), those of block g from
// start[g] to start[g + 1].
struct BlockList {
  std::vector<Entry> entries;
  std::vector<std::size_t> start;
  std::size_t count() const { return start.size() - 1; }
};

// Which pieces reach which blocks within layers zBegin <= k < zEnd; `poll` throws on an interrupt.
template <typename Poll>
BlockList listBlocks(const std::vector<RodPieces>& rods, int zBegin, int zEnd, const Poll& poll) {
  std::vector<std::vector<Entry>> perRod(rods.size());
  tbb::parallel_for(std::size_t(0), rods.size(), [&](std::size_t r) {
    const RodPieces& rod = rods[r];
    if (rod.box.empty() || rod.box.max().z() < zBegin || rod.box.min().z() >= zEnd) return;
    for (std::size_t p = 0; p < rod.pieces.size(); ++p) {
      if (p % 1024 == 0) poll();
      openvdb::CoordBBox b = rod.pieces[p].box;
      b.min().z() = std::max(b.min().z(), zBegin);
      b.max().z() = std::min(b.max().z(), zEnd - 1);
      if (b.empty()) continue;
      for (int k = b.min().z() >> kLeafLog2; k <= b.max().z() >> kLeafLog2; ++k)
        for (int j = b.min().y() >> kLeafLog2; j <= b.max().y() >> kLeafLog2; ++j)
          for (int i = b.min().x() >> kBlockXLog2; i <= b.max().x() >> kBlockXLog2; ++i)
            perRod[r].push_back({packBlock(i, j, k), std::uint32_t(r), std::uint32_t(p)});
    }
  });
  BlockList list;
  std::size_t total = 0;
  for (const auto& v : perRod) total += v.size();
  list.entries.reserve(total);
  for (auto& v : perRod) {
    list.entries.insert(list.entries.end(), v.begin(), v.end());
    std::vector<Entry>().swap(v);
  }
  poll();
  tbb::parallel_sort(list.entries.begin(), list.entries.end());
  poll();
  for (std::size_t e = 0; e < list.entries.size(); ++e)
    if (e == 0 || list.entries[e].block != list.entries[e - 1].block) list.start.push_back(e);
  list.start.push_back(list.entries.size());
  return list;
}

using BlockLeaves = std::array<std::unique_ptr<LeafT>, kBlockLeaves>;

// Block g of the list, its pieces added in sorted order within the band, into `leaves` (none where
// no piece reaches a voxel of the band).
template <typename Poll>
void buildBlock(LeafBuilder& builder, const std::vector<RodPieces>& rods, const BlockList& list, std::size_t g, int zBegin,
                int zEnd, const Poll& poll, BlockLeaves& leaves) {
  const openvdb::Coord origin = blockOrigin(list.entries[list.start[g]].block);
  openvdb::CoordBBox blockBox(origin, origin + openvdb::Coord((kLeafDim << kBlockLeavesLog2) - 1, kLeafDim - 1, kLeafDim - 1));
  blockBox.min().z() = std::max(blockBox.min().z(), zBegin);
  blockBox.max().z() = std::min(blockBox.max().z(), zEnd - 1);
  builder.clear();
  bool touched = false;
  for (std::size_t e = list.start[g]; e < list.start[g + 1]; ++e) {
    if ((e - list.start[g]) % 8 == 7) poll();
    const Entry& entry = list.entries[e];
    openvdb::CoordBBox b = rods[entry.rod].pieces[entry.piece].box;
    b.intersect(blockBox);
    if (b.empty()) continue;
    builder.addPiece(int(entry.rod), int(entry.piece), b);
    touched = true;
  }
  if (!touched) return;
  builder.emit([&](int l) -> LeafT& {
    leaves[static_cast<std::size_t>(l)] = std::make_unique<LeafT>(origin.offsetBy(l * kLeafDim, 0, 0), 0.0f, false);
    return *leaves[static_cast<std::size_t>(l)];
  });
}

}  // namespace

Rasterizer::Rasterizer(const geometry::RodStructure& structure, const PrinterGrid& grid, RasterOptions options)
    : structure_(&structure), grid_(grid), options_(std::move(options)) {
  rods_.resize(structure.rods.size());
  // Voxels are only ever emitted inside the design's bounding box (geometry::Rod::bounds holds every
  // rod's solid), the part bounds the job writer checks.
  const geometry::Box3 bounds = structure.bounds();
  partBounds_ = bounds.isEmpty() ? openvdb::CoordBBox()
                                 : grid_.voxelsWithin({bounds.min().x(), bounds.min().y(), bounds.min().z()},
                                                      {bounds.max().x(), bounds.max().y(), bounds.max().z()});
  tbb::task_arena arena(options_.threads > 0 ? options_.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(std::size_t(0), rods_.size(), [&](std::size_t r) {
      detail::RodPieces pieces = detail::buildRodPieces(structure.rods[r], grid_, options_.wasInterrupted);
      pieces.box = openvdb::CoordBBox();
      for (RodPiece& p : pieces.pieces) {
        p.box.intersect(partBounds_);
        if (!p.box.empty()) pieces.box.expand(p.box);
      }
      rods_[r] = std::move(pieces);
    });
  });
}

void Rasterizer::checkInterrupt() const {
  if (options_.wasInterrupted && options_.wasInterrupted()) throw Interrupted("rasterizer: interrupted");
}

Rasterizer::~Rasterizer() = default;
Rasterizer::Rasterizer(Rasterizer&&) noexcept = default;
Rasterizer& Rasterizer::operator=(Rasterizer&&) noexcept = default;

std::size_t Rasterizer::pieceCount() const {
  std::size_t n = 0;
  for (const RodPieces& r : rods_) n += r.pieces.size();
  return n;
}

Rasterization Rasterizer::rasterizeLayers(int zBegin, int zEnd) const {
  tbb::task_arena arena(options_.threads > 0 ? options_.threads : tbb::task_arena::automatic);
  return arena.execute([&] { return run(zBegin, zEnd); });
}

Rasterization Rasterizer::run(int zBegin, int zEnd) const {
  Rasterization out;
  out.grid = openvdb::FloatGrid::create(0.0f);
  out.grid->setName(kModulusGridName);
  out.grid->setTransform(grid_.transform());
  out.grid->setGridClass(openvdb::GRID_UNKNOWN);
  out.voxelsPerRod.assign(rods_.size(), 0);
  zBegin = std::max(zBegin, 0);
  zEnd = std::min(zEnd, grid_.dims.z());
  if (zBegin >= zEnd) return out;

  const auto poll = [this] { checkInterrupt(); };
  const BlockList blocks = listBlocks(rods_, zBegin, zEnd, poll);
  // Each block built by one task from its pieces, in sorted order.
  struct ThreadState {
    std::unique_ptr<LeafBuilder> builder;
  };
  tbb::enumerable_thread_specific<ThreadState> states;
  std::vector<BlockLeaves> leaves(blocks.count());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks.count()), [&](const tbb::blocked_range<std::size_t>& range) {
    ThreadState& state = states.local();
    if (!state.builder) state.builder.reset(new LeafBuilder(*structure_, rods_, grid_, options_.wasInterrupted));  // slots mostly uninitialized
    for (std::size_t g = range.begin(); g != range.end(); ++g) {
      poll();
      buildBlock(*state.builder, rods_, blocks, g, zBegin, zEnd, poll, leaves[g]);
    }
  });

  checkInterrupt();  // a builder that saw the interrupt while settling a block left it incomplete
  for (ThreadState& s : states) {
    out.exactEvaluations += s.builder->exactEvaluations;
    for (std::size_t r = 0; r < rods_.size(); ++r) out.voxelsPerRod[r] += s.builder->voxelsPerRod[r];
  }
  openvdb::FloatTree& tree = out.grid->tree();
  for (BlockLeaves& blockLeaves : leaves)
    for (std::unique_ptr<LeafT>& leaf : blockLeaves)
      if (leaf) tree.addLeaf(leaf.release());
  return out;
}

Rasterization rasterize(const geometry::RodStructure& structure, const PrinterGrid& grid, RasterOptions options) {
  return Rasterizer(structure, grid, options).rasterize();
}

}  // namespace rodfab::voxel
