// The caps' voxel loop: the round cap's half-ball (or a flat cap's near-plane voxels) beyond a rod's end
// plane, four voxels a step.
#pragma GCC diagnostic ignored "-Wpsabi"  // see raster_clips.hpp

#include "common/cpu_clones.hpp"
#include "voxel/leaf_builder.hpp"

#include <cmath>
#include <limits>

namespace rodfab::voxel::detail {

namespace {

constexpr double kCapRoundOff = 1e-9;  // round-off in the cap's distance, relative to its radius
constexpr double kSurelyInside = 1.0 - kCapRoundOff, kSurelyOutside = 1.0 + kCapRoundOff;

// The voxels of four rows of a cap that can do anything, each row as `bounds` narrows it: those near
// the end plane (|a| <= nearPlane, sent to the exact test) and, for round caps, those of the ball
// (|wx| <= sqrt(rest), wx = wxRow + gx i, rest = radius^2 - wy^2 - wz^2 with the radius a little
// enlarged). Narrows `bounds` to the hull of the two ranges, as conservatively as the other clips (see
// Slope); marks the rows where both are empty missed. Outside them the loop would skip every voxel:
// the ball clip keeps the rows of an axis-aligned cap to its half-ball instead of the half-cylinder
// (2/3 of the voxels) or the half-box (a third). Lane by lane the expressions of the row-by-row clip
// this replaced (one vector square root for four rows), so each row gets the same range.
[[gnu::always_inline]] inline void capRows(bool round, Double4 aRow, double nearPlane, const Slope& rising, const Slope& falling,
                                           Double4 wxRow, Double4 rest, const Slope& alongX, const Slope& againstX,
                                           FourRowBounds& bounds) {
  FourRowBounds near, ball;
  rising.bound(aRow + nearPlane, near.lo, near.hi, near.missed);
  falling.bound(nearPlane - aRow, near.lo, near.hi, near.missed);
  ball.missed = ~Mask4{};
  if (round) {
    ball.missed = ~(rest >= 0.0);
    const Double4 reach = squareRoot(rest);  // not a number where rest < 0; those lanes are missed
    alongX.bound(wxRow + reach, ball.lo, ball.hi, ball.missed);
    againstX.bound(reach - wxRow, ball.lo, ball.hi, ball.missed);
  }
  bounds.missed |= near.missed & ball.missed;
  // std::min and std::max of the two ranges where both hold voxels, else the one that does.
  const Double4 lo = ball.missed ? near.lo : near.missed ? ball.lo : smallerOf(near.lo, ball.lo);
  const Double4 hi = ball.missed ? near.hi : near.missed ? ball.hi : largerOf(near.hi, ball.hi);
  bounds.lo = largerOf(bounds.lo, lo);
  bounds.hi = smallerOf(bounds.hi, hi);
}

}  // namespace

// What the loop over a cap's row needs about the cap (see cap).
struct LeafBuilder::CapPiece {
  int rod, index;
  bool atEnd, round;
  double nearPlane, invCap, gxPlane, gxOffset;
  float endModulus;
};

// Row (j, k) of a cap from voxel lo to hi, four voxels a step: the plane value and the distance to the
// end point (with its square root) for four neighbours at once, lane by lane the scalar expressions;
// then the decisions per voxel, in order.
[[gnu::always_inline]] inline void LeafBuilder::capRowVoxels(const CapPiece& c, double aRow, double wxRow, double wyz, int lo, int hi,
                                                             int j, int k) {
  Double4 iv = double(lo) + Double4{0.0, 1.0, 2.0, 3.0};
  for (int i = lo; i <= hi; i += 4, iv += 4.0) {
    const Double4 a = aRow + c.gxPlane * iv;
    const Mask4 beyond = c.atEnd ? (a >= 0.0) : (a < 0.0);
    const Mask4 near = absolute(a) <= c.nearPlane;
    Double4 g = Double4{} + std::numeric_limits<double>::infinity();  // flat caps: only the near-plane voxels
    if (c.round) {
      const Double4 wx = wxRow + c.gxOffset * iv;
      g = squareRoot(wx * wx + wyz) * c.invCap;
    }
    // Inside for sure; the depth's round-off (1e-9 of the radius at most) is within the tie
    // tolerance, so it counts as exact.
    const Mask4 sure = beyond & ~near & (g < kSurelyInside);
    const unsigned sureLanes = laneBits(sure);
    if (i + 3 <= hi && sureLanes == 0xfu) {
      addFourCapCandidates(offset(i, j, k), g, c.endModulus, c.rod, c.index, i, j, k);
      continue;
    }
    // A row's partial last quad, inside for sure, into empty slots (its lanes' bits: hi - i is 0 to 2
    // there; before a row's last quad the shift would pass the word, undefined behaviour).
    if (i + 3 > hi) {
      const unsigned inRow = (2u << (hi - i)) - 1u;
      if ((sureLanes & inRow) == inRow && capsIntoEmptySlots(offset(i, j, k), g, inRow, c.endModulus, c.rod, c.index)) continue;
    }
    for (int l = 0; l < 4 && i + l <= hi; ++l) {
      if (!beyond[l] || (!near[l] && g[l] > kSurelyOutside)) continue;
      if (sure[l]) addCapCandidate(offset(i + l, j, k), g[l], c.endModulus, c.rod, c.index, i + l, j, k);
      else addCandidate(exact(c.rod, c.index, i + l, j, k), offset(i + l, j, k), i + l, j, k);
    }
  }
}

// Cloned for AVX2 like sweep (no FMA there either, so the clones compute the same bits). A layer's
// rows four at a time: their plane and offset values and their voxel ranges (the clips lane by lane);
// then row by row (capRowVoxels).
RODFAB_CLONES("avx2", "default") void LeafBuilder::cap(int rod, int pieceIndex, const RodPiece& piece,
                                                       const openvdb::CoordBBox& box) {
  const RodPieces& rp = rods_[rod];
  const geometry::Rod& r = structure_.rods[rod];
  const AffineInIndex& plane = rp.planes[piece.plane];
  const bool atEnd = piece.kind == RodPiece::Kind::EndCap, round = r.caps() == geometry::CapStyle::Round;
  // Beyond the plane: a >= 0 past the end, a < 0 before the beginning (the complements of the
  // swept pieces' conditions, evaluated identically).
  const double sign = atEnd ? 1.0 : -1.0;
  const CapPiece c{rod, pieceIndex, atEnd, round, capPlaneTolerance(r.section().boundingRadius()), rp.inverseCapRadius,
                   plane.gx, piece.capOffset[0].gx, piece.capModulus};
  AxisCylinder cylinder(grid_, piece);
  const Slope slope(sign * plane.gx), rising(plane.gx), falling(-plane.gx);
  const Slope alongX(piece.capOffset[0].gx), againstX(-piece.capOffset[0].gx);
  // A little more than the largest |p - end point| the loop keeps (g <= 1 + kCapRoundOff, computed):
  // the margin (1e-9 of the radius) dwarfs the round-off of the distance and of the clip.
  const double ballRadiusSquared = ((1.0 + 2.0 * kCapRoundOff) / c.invCap) * ((1.0 + 2.0 * kCapRoundOff) / c.invCap);
  const RowLanes planeLanes(plane), wxLanes(piece.capOffset[0]), wyLanes(piece.capOffset[1]), wzLanes(piece.capOffset[2]);
  for (int k = box.min().z(); k <= box.max().z(); ++k) {
    int jLo = box.min().y(), jHi = box.max().y();
    if (!cylinder.layer(k, jLo, jLo, jHi)) continue;
    const LayerRows planeRows(planeLanes, k), wxRows(wxLanes, k), wyRows(wyLanes, k), wzRows(wzLanes, k);
    for (int j4 = jLo; j4 <= jHi; j4 += 4) {
      const Double4 jv = double(j4) + Double4{0.0, 1.0, 2.0, 3.0};
      const Double4 aRow = planeRows.at(jv), wxRow = wxRows.at(jv), wy = wyRows.at(jv), wz = wzRows.at(jv);
      const Double4 wyz = wy * wy + wz * wz;
      // The clips in the order the rows were once clipped one by one (the plane, the cylinder, the
      // cap's ranges), each narrowing the same bounds; rounded once (ceil and floor are monotone).
      FourRowBounds bounds;
      slope.bound(sign * aRow, bounds.lo, bounds.hi, bounds.missed);
      cylinder.rows(j4, bounds.lo, bounds.hi, bounds.missed);
      capRows(round, aRow, c.nearPlane, rising, falling, wxRow, ballRadiusSquared - wyz, alongX, againstX, bounds);
      Int4 first, last;
      Mask4 empty;
      bounds.round(box.min().x(), box.max().x(), first, last, empty);
      for (unsigned kept = ~laneBits(empty) & ((2u << std::min(3, jHi - j4)) - 1u); kept != 0; kept &= kept - 1u) {
        const int l = __builtin_ctz(kept);
        capRowVoxels(c, aRow[l], wxRow[l], wyz[l], first[l], last[l], j4 + l, k);
      }
    }
  }
}

}  // namespace rodfab::voxel::detail
