// The swept pieces' voxel loop: rows of the slab between a piece's two normal planes, four voxels a step.
#pragma GCC diagnostic ignored "-Wpsabi"  // see raster_clips.hpp

#include "common/cpu_clones.hpp"
#include "voxel/leaf_builder.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rodfab::voxel::detail {

namespace {

// The slab a >= 0 > b between a piece's planes within a box: the layers, then each layer's rows, that
// can hold a voxel of it, bounded by the planes' extremes over the box's i (and j) before any row is
// set up.
class SlabClip {
public:
  SlabClip(const AffineInIndex& a, const AffineInIndex& b, const openvdb::CoordBBox& box)
      : a_(a), b_(b), box_(box), aMaxI_(extreme(a.gx, box.min().x(), box.max().x(), true)),
        bMinI_(extreme(b.gx, box.min().x(), box.max().x(), false)), slopeAy_(a.gy), slopeBy_(-b.gy) {}
  // The box's layers that can hold a voxel of the slab; false when none.
  [[gnu::always_inline]] bool layers(int& kLo, int& kHi) const {
    const openvdb::Coord &bmin = box_.min(), &bmax = box_.max();
    kLo = bmin.z();
    kHi = bmax.z();
    return clipHalfLine(a_.c + aMaxI_ + extreme(a_.gy, bmin.y(), bmax.y(), true), a_.gz, kLo, kHi) &&
           clipHalfLine(-(b_.c + bMinI_ + extreme(b_.gy, bmin.y(), bmax.y(), false)), -b_.gz, kLo, kHi);
  }
  // Narrows [jLo, jHi] to layer k's rows that can hold a voxel of the slab; false when none.
  [[gnu::always_inline]] bool rows(int k, int& jLo, int& jHi) const {
    return slopeAy_.clip(a_.c + a_.gz * k + aMaxI_, jLo, jHi) && slopeBy_.clip(-(b_.c + b_.gz * k + bMinI_), jLo, jHi);
  }

private:
  static double extreme(double g, int from, int to, bool largest) {
    return largest ? std::max(g * from, g * to) : std::min(g * from, g * to);
  }
  const AffineInIndex &a_, &b_;
  const openvdb::CoordBBox& box_;
  double aMaxI_, bMinI_;
  Slope slopeAy_, slopeBy_;
};

}  // namespace

// What sweep's steps share about the piece.
struct LeafBuilder::SweptPiece {
  int rod, index;
  const RodPiece& piece;
  const AffineInIndex &planeA, &planeB;
  Slope slopeA, slopeB;  // of the planes along i, for the rows' bounds
  bool rectangle;
  float floatErrorBound;
  ShellThresholds shell;
};

// A row's values at i = 0 of the planes and of the frame coordinates measured in them.
struct LeafBuilder::SweptRowStart {
  double a, b, x1a, x2a, x1b, x2b;
};

// Four neighbours' swept estimate (see estimateSwept) and what the decisions per voxel need: `test` is
// what the tolerance shell is tested on, the gauge squared for round sections (the encoded depth as it
// is), the max-norm gauge for rectangles (encoded depth 1 - gauge).
struct LeafBuilder::SweptQuad {
  Double4 test, encodedDepth, modulus;
  Mask4 inSlab, sure;
};

template <bool Full>
[[gnu::always_inline]] inline LeafBuilder::SweptQuad LeafBuilder::sweptQuad(bool rectangle, const SweptRowStart& r, Double4 iv) const {
  const SweptLanes& lanes = swept_;
  const Double4 av = r.a + lanes.gxA * iv, bv = r.b + lanes.gxB * iv;
  const SweptEstimateOf<Double4> e = estimateSwept<Full>(lanes, av, bv, r.x1a + lanes.gx1Begin * iv, r.x2a + lanes.gx2Begin * iv,
                                                   r.x1b + lanes.gx1End * iv, r.x2b + lanes.gx2End * iv);
  SweptQuad q;
  if (rectangle) {
    const Double4 g1 = absolute(e.x1) * lanes.iA, g2 = absolute(e.x2) * lanes.iB;
    q.test = g1 < g2 ? g2 : g1;  // std::max(g1, g2), lane by lane
    q.encodedDepth = 1.0 - q.test;
  } else {
    q.test = (e.x1 * lanes.iA) * (e.x1 * lanes.iA) + (e.x2 * lanes.iB) * (e.x2 * lanes.iB);
    q.encodedDepth = q.test;
  }
  q.modulus = estimateModulus<Full>(lanes, e);
  q.inSlab = (av >= 0.0) & (bv < 0.0);
  q.sure = q.inSlab & (q.test < lanes.sureInsideBelow);
  return q;
}

// Voxels i .. min(i + 3, hi) of a row: four inside for sure go into empty slots with one store each
// (the common case) or through addFourSurelyInside, as does a row's partial last quad into empty slots;
// otherwise voxel by voxel, the borderline ones to the exact test. Returns the slots newly filled.
[[gnu::always_inline]] inline int LeafBuilder::settleQuad(const SweptPiece& s, const SweptQuad& q, int row, int i, int hi, int j,
                                                          int k) {
  const int n = (row << kBlockXLog2) | (i & (kBlockX - 1));
  if (i + 3 <= hi) {
    if (laneBits(q.sure) == 0xfu) {
      const Float4 value = __builtin_convertvector(q.modulus, Float4);
      if (storeFourIntoEmpty(n, q.encodedDepth, value, swept_.errorBounds, swept_.owners, 0xfu)) return 4;
      return addFourSurelyInside(n, q.encodedDepth, value, s.floatErrorBound, s.rod, s.index, i, j, k);
    }
  } else if (const unsigned inRow = (2u << (hi - i)) - 1u;
             (laneBits(q.sure) & inRow) == inRow &&
             storeFourIntoEmpty(n, q.encodedDepth, __builtin_convertvector(q.modulus, Float4), swept_.errorBounds, swept_.owners, inRow)) {
    return hi - i + 1;  // a row's last, partial quad (most rows of short pieces end in one), in one store
  }
  int fresh = 0;
  for (int l = 0; l < 4 && i + l <= hi; ++l) {
    if (!q.inSlab[l] || q.test[l] > s.shell.sureOutsideAbove) continue;
    if (q.sure[l])
      fresh += addSurelyInside(n + l, q.encodedDepth[l], s.floatErrorBound, static_cast<float>(q.modulus[l]), s.rod, s.index, i + l, j, k);
    else
      addCandidate(exact(s.rod, s.index, i + l, j, k), n + l, i + l, j, k);
  }
  return fresh;
}

// Row (j, k) from voxel lo to hi (lo <= hi), four voxels a step (see estimateSwept); the decisions per
// voxel. Returns the slots newly filled.
template <bool Full>
[[gnu::always_inline]] inline int LeafBuilder::sweepRow(const SweptPiece& s, const SweptRowStart& r, int lo, int hi, int j, int k) {
  const int row = rowOf(j, k);
  int fresh = 0;
  Double4 iv = double(lo) + Double4{0.0, 1.0, 2.0, 3.0};
  int i = lo;
  do {  // a row has a voxel (sweepLayer skips empty rows): no test before the first quad
    fresh += settleQuad(s, sweptQuad<Full>(s.rectangle, r, iv), row, i, hi, j, k);
    i += 4;
    iv += 4.0;
  } while (i <= hi);
  return fresh;
}

// Layer k's rows jLo .. jHi, set up four at a time (the planes' rows and bounds, the cylinder's square
// root), each lane as the scalar clips compute it; then row by row. Returns the slots newly filled.
template <bool Full>
[[gnu::always_inline]] inline int LeafBuilder::sweepLayer(const SweptPiece& s, const openvdb::CoordBBox& box, const AxisCylinder& cylinder,
                                                           int k, int jLo, int jHi) {
  const SweptLanes& lanes = swept_;
  const LayerRows planeA(lanes.planeARows, k), planeB(lanes.planeBRows, k);
  const LayerRows x1Begin(lanes.x1BeginRows, k), x2Begin(lanes.x2BeginRows, k), x1End(lanes.x1EndRows, k), x2End(lanes.x2EndRows, k);
  int fresh = 0;
  for (int j4 = jLo; j4 <= jHi; j4 += 4) {
    const Double4 jv = double(j4) + Double4{0.0, 1.0, 2.0, 3.0};
    const FourRows rows(planeA, planeB, s.slopeA, s.slopeB, cylinder, j4, jv);
    Int4 first, last;
    Mask4 empty;
    rows.round(box.min().x(), box.max().x(), first, last, empty);
    // The frame coordinates' rows for the four rows at once too.
    const Double4 x1a = x1Begin.at(jv), x2a = x2Begin.at(jv), x1b = x1End.at(jv), x2b = x2End.at(jv);
    // The rows with voxels as bits, visited in order: one branch a row, where the loop's bound and the
    // empty rows were two hard to predict (rows kept vary from 0 to 4 a group).
    for (unsigned kept = ~laneBits(empty) & ((2u << std::min(3, jHi - j4)) - 1u); kept != 0; kept &= kept - 1u) {
      const int l = __builtin_ctz(kept), j = j4 + l;
      const int lo = first[l], hi = last[l];
      const SweptRowStart start{rows.a[l], rows.b[l], x1a[l], x2a[l], x1b[l], x2b[l]};
      fresh += sweepRow<Full>(s, start, lo, hi, j, k);
    }
  }
  return fresh;
}

// Cloned for AVX2 (four lanes in one register; AVX2 brings no FMA, so no multiply-add is fused and
// the clone computes the bits the baseline does), chosen at load time. Flattened: with the loop there
// twice (with and without the full estimate's terms, RodPiece) GCC stopped inlining clearOverlap and
// addCandidate into it, which cost more than the terms saved (spring +1 % of instructions).
[[gnu::flatten]] RODFAB_CLONES("avx2", "default") void LeafBuilder::sweep(int rod, int pieceIndex, const RodPiece& piece,
                                                                          const openvdb::CoordBBox& box) {
  const RodPieces& rp = rods_[rod];
  const AffineInIndex& planeA = rp.planes[piece.plane];
  const AffineInIndex& planeB = rp.planes[piece.plane + 1];
  const SlabClip slab(planeA, planeB, box);
  int kLo, kHi;
  if (!slab.layers(kLo, kHi)) return;
  const bool rectangle = structure_.rods[rod].section().shape == geometry::SectionShape::Rectangle;
  const SweptPiece s{rod,
                     pieceIndex,
                     piece,
                     planeA,
                     planeB,
                     Slope(planeA.gx),
                     Slope(-planeB.gx),
                     rectangle,
                     roundedUpToFloat(piece.normalizedRadiusErrorBound),
                     ShellThresholds(piece.normalizedRadiusErrorBound, rectangle)};
  swept_ = SweptLanes(piece, planeA, planeB, rp.inverseHalfWidth, rp.inverseHalfHeight, s.shell.sureInsideBelow,
                      s.floatErrorBound, owner(rod, pieceIndex));
  AxisCylinder cylinder(grid_, piece);
  const bool full = needsFullEstimate(piece);
  std::uint64_t fresh = 0;  // slots newly filled
  for (int k = kLo; k <= kHi; ++k) {
    int jLo = box.min().y(), jHi = box.max().y();
    if (!slab.rows(k, jLo, jHi) || !cylinder.layer(k, box.min().y(), jLo, jHi)) continue;
    fresh += static_cast<std::uint64_t>(full ? sweepLayer<true>(s, box, cylinder, k, jLo, jHi) : sweepLayer<false>(s, box, cylinder, k, jLo, jHi));
  }
  // The rod's tally once per piece (the overlap rule moves voxels between tallies meanwhile; only the
  // sums are read, after every block).
  voxelsPerRod[static_cast<std::size_t>(rod)] += fresh;
}

}  // namespace rodfab::voxel::detail
