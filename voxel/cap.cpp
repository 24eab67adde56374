// The caps' voxel loop: the round cap's half-ball (or a flat cap's near-plane voxels) beyond a rod's end
// plane, four voxels a step.
#pragma GCC diagnostic ignored "-Wpsabi"  // see raster_clips.hpp

#include "voxel/leaf_builder.hpp"

#include <cmath>
#include <limits>

namespace rodfab::voxel::detail {

namespace {

// The voxels of a cap's row that can do anything: those near the end plane (|a| <= nearPlane, sent
// to the exact test) and, for round caps, those of the ball (|wx| <= sqrt(rest), wx = wxRow + gx i,
// rest = radius^2 - wy^2 - wz^2 with the radius a little enlarged). Narrows `bounds` to the hull of
// the two ranges, as conservatively as the other clips (see Slope); false when both are empty. Outside
// them the loop would skip every voxel: the ball clip keeps the rows of an axis-aligned cap to its
// half-ball instead of the half-cylinder (2/3 of the voxels) or the half-box (a third).
[[gnu::always_inline]] inline bool capRow(bool round, double aRow, double nearPlane, const Slope& rising, const Slope& falling, double wxRow,
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

}  // namespace

// Cloned for AVX2 like sweep (no FMA there either, so the clones compute the same bits). Four voxels
// a step: the plane value and the distance to the end point (with its square root) for four
// neighbours at once, lane by lane the scalar expressions; then the decisions per voxel, in order.
[[gnu::target_clones("avx2", "default")]] void LeafBuilder::cap(int rod, int pieceIndex, const RodPiece& piece,
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
      // Rows behind the plane within the box are skipped before the two square roots (rounding
      // twice gives the range rounding once does: ceil and floor are monotone).
      if (!slope.bound(sign * aRow, bounds.lo, bounds.hi) || !bounds.round(lo, hi) || !cylinder.row(j, bounds) ||
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
        const unsigned sureLanes = laneBits(sure);
        if (i + 3 <= hi && sureLanes == 0xfu) {
          addFourCapCandidates(offset(i, j, k), g, endModulus, rod, pieceIndex, i, j, k);
          continue;
        }
        // A row's partial last quad, inside for sure, into empty slots.
        if (const unsigned inRow = (2u << (hi - i)) - 1u; i + 3 > hi && (sureLanes & inRow) == inRow &&
                                                          capsIntoEmptySlots(offset(i, j, k), g, inRow, endModulus, rod, pieceIndex))
          continue;
        for (int l = 0; l < 4 && i + l <= hi; ++l) {
          if (!beyond[l] || (!near[l] && g[l] > kSurelyOutside)) continue;
          if (sure[l]) addCapCandidate(offset(i + l, j, k), g[l], endModulus, rod, pieceIndex, i + l, j, k);
          else addCandidate(exact(rod, pieceIndex, i + l, j, k), offset(i + l, j, k), i + l, j, k);
        }
      }
    }
  }
}

}  // namespace rodfab::voxel::detail
