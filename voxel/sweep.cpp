// The swept pieces' voxel loop: rows of the slab between a piece's two normal planes, four voxels a step.
#pragma GCC diagnostic ignored "-Wpsabi"  // see raster_clips.hpp

#include "voxel/leaf_builder.hpp"

#include <cmath>
#include <limits>

namespace rodfab::voxel::detail {

// Cloned for AVX2 (four lanes in one register; AVX2 brings no FMA, so no multiply-add is fused and
// the clone computes the bits the baseline does), chosen at load time.
[[gnu::target_clones("avx2", "default")]] void LeafBuilder::sweep(int rod, int pieceIndex, const RodPiece& piece,
                                                                  const openvdb::CoordBBox& box) {
  const RodPieces& rp = rods_[rod];
  const AffineInIndex& planeA = rp.planes[piece.plane];
  const AffineInIndex& planeB = rp.planes[piece.plane + 1];
  const double iA = rp.inverseHalfWidth, iB = rp.inverseHalfHeight;
  const bool rectangle = structure_.rods[rod].section().shape == geometry::SectionShape::Rectangle;
  const float floatErrorBound = roundedUpToFloat(piece.normalizedRadiusErrorBound);
  const ShellThresholds shell(piece.normalizedRadiusErrorBound, rectangle);
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
  struct {
    Double4 iA, iB, sureInsideBelow;
  } const gauges{broadcast(iA), broadcast(iB), broadcast(shell.sureInsideBelow)};
  // Their addresses made known: the lanes then stay in memory, read by the vector instructions as
  // operands. Kept as values, GCC split them into registers, then spilled, copied or broadcast
  // them again at every row (some 40 instructions a row, 1.3 quads a row on the curved lattice).
  asm volatile("" : : "r"(&lanes), "r"(&gauges) : "memory");
  for (int k = kLo; k <= kHi; ++k) {
    int jLo = bmin.y(), jHi = bmax.y();
    if (!slopeAy.clip(planeA.c + planeA.gz * k + aMaxI, jLo, jHi) || !slopeBy.clip(-(planeB.c + planeB.gz * k + bMinI), jLo, jHi) ||
        !cylinder.layer(k, bmin.y(), jLo, jHi))
      continue;
    // Rows set up four at a time (the planes' rows and bounds, the cylinder's square root), each lane
    // as the scalar clips compute it; then row by row as before.
    for (int j4 = jLo; j4 <= jHi; j4 += 4) {
      const FourRows rows(planeA, planeB, slopeA, slopeB, cylinder, j4, k);
      for (int l = 0; l < 4 && j4 + l <= jHi; ++l) {
        const int j = j4 + l;
        const double aRow = rows.a[l], bRow = rows.b[l];
        RowBounds bounds{rows.lo[l], rows.hi[l]};
        int lo = bmin.x(), hi = bmax.x();
        if (rows.missed[l] || !bounds.round(lo, hi)) continue;
        const double x1aRow = piece.x1Begin.row(j, k), x2aRow = piece.x2Begin.row(j, k);
        const double x1bRow = piece.x1End.row(j, k), x2bRow = piece.x2End.row(j, k);
        const int row = rowOf(j, k);
        std::uint64_t fresh = 0;
        // Four voxels at a time (see estimateSwept); the decisions per voxel. `test` is what the
        // tolerance shell is tested on: the gauge squared for round sections (encoded depth
        // as it is), the max-norm gauge for rectangles (encoded depth 1 - gauge).
        Double4 iv = double(lo) + Double4{0.0, 1.0, 2.0, 3.0};
        for (int i = lo; i <= hi; i += 4, iv += 4.0) {
          const Double4 av = aRow + lanes.gxA * iv, bv = bRow + lanes.gxB * iv;
          const detail::SweptEstimateOf<Double4> e =
              detail::estimateSwept(lanes, av, bv, x1aRow + lanes.gx1Begin * iv, x2aRow + lanes.gx2Begin * iv,
                                    x1bRow + lanes.gx1End * iv, x2bRow + lanes.gx2End * iv);
          Double4 test, encodedDepth;
          if (rectangle) {
            const Double4 g1 = absolute(e.x1) * gauges.iA, g2 = absolute(e.x2) * gauges.iB;
            test = g1 < g2 ? g2 : g1;  // std::max(g1, g2), lane by lane
            encodedDepth = 1.0 - test;
          } else {
            test = (e.x1 * gauges.iA) * (e.x1 * gauges.iA) + (e.x2 * gauges.iB) * (e.x2 * gauges.iB);
            encodedDepth = test;
          }
          const Double4 modulus = detail::estimateModulus(lanes, e.lambda);
          const Mask4 inSlab = (av >= 0.0) & (bv < 0.0);
          const Mask4 sure = inSlab & (test < gauges.sureInsideBelow);
          if (i + 3 <= hi && (sure[0] & sure[1] & sure[2] & sure[3])) {
            // The common case: four neighbours inside for sure; into empty slots with one store each.
            const int n = (row << kBlockXLog2) | (i & (kBlockX - 1));
            std::uint64_t& word = filled_[static_cast<std::size_t>(row)];
            if (((word >> (i & (kBlockX - 1))) & 0xfu) == 0) {
              storeFour(n, encodedDepth, __builtin_convertvector(modulus, Float4), floatErrorBound, owner(rod, pieceIndex));
              word |= std::uint64_t(0xf) << (i & (kBlockX - 1));
              fresh += 4;
            } else {
              fresh += addFourSurelyInside(n, encodedDepth, __builtin_convertvector(modulus, Float4), floatErrorBound, rod,
                                           pieceIndex, i, j, k);
            }
            continue;
          }
          for (int l = 0; l < 4 && i + l <= hi; ++l) {
            if (!inSlab[l] || test[l] > shell.sureOutsideAbove) continue;
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
}

}  // namespace rodfab::voxel::detail
