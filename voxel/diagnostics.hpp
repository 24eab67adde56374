// What a design will cost the rasterizer, and which rods the printer cannot resolve: checks for the
// slicer to run before allocating (estimateRaster) and to print as warnings (findThinRods).
#pragma once

#include "geometry/rod.hpp"
#include "voxel/printer_grid.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace rodfab::voxel {

// Memory the rasterizer needs for `structure` on `grid`, from the design alone: no pieces are built
// and nothing is allocated (time linear in the rods' polyline samples). Byte counts are bytes,
// voxel counts voxels. Thread-safe.
struct RasterEstimate {
  // Upper bound on the pieces the Rasterizer cuts the rods into (each rod's refinement stops at its
  // budget, rod_pieces.hpp) and on the bytes it holds for them from construction to destruction.
  std::uint64_t maxPieces = 0;
  double pieceBytes = 0.0;
  // Bytes the Rasterizer holds per piece (pieceBytes = maxPieces of them): with the pieces built, their
  // real count (Rasterizer::pieceCount) times this replaces the budget's bound, often 10 times lower.
  static double bytesPerPiece();
  // Expected active voxels: the rods' volumes (sections times lengths plus caps) over the voxel
  // volume. Within a few percent for rods bent less tightly than their radius; overlaps at joints are
  // counted in full, and sections folding over in bends tighter than the radius add up to ~30 %.
  double activeVoxels = 0.0;
  // Expected OpenVDB leaves (8^3 voxels) holding them (each straight piece of each rod's polyline
  // widened by a leaf's box, its section counted at its longest cut by a layer times its height, and
  // overlaps at joints counted in full: an upper estimate, 1.0 to 1.9 times the leaves built on the
  // benchmark classes and the bundled examples, and never more leaves than the envelope holds), and
  // the bytes of the grid holding the whole design (Rasterizer::rasterize,
  // `rodfab voxelize`): its leaves with their value buffers, and its internal nodes, at most those the
  // envelope spans. The band figures below are capped the same way (a layer by the envelope's area).
  double leaves = 0.0;
  double gridBytes = 0.0;
  // With bandLayers > 0: the leaves and bytes of the grid of the fullest band of that many layers
  // (Rasterizer::rasterizeLayers): each rod's leaves spread evenly over the layers each piece of it
  // reaches (its section's real extent in z in the rod's frame, its caps and half a leaf), a band holding
  // the whole 8-layer slabs its layers and the next one touch (RasterProfile::estimate: or its layers
  // only); its internal nodes at most those a band of the envelope spans.
  double bandLeaves = 0.0;
  double bandBytes = 0.0;
  // With bandLayers > 0: active voxels of the fullest layer, an upper estimate: each piece of each rod
  // adds the most a layer through it can hold (its length times the section a layer cuts, or its volume
  // over its rise when steep) to every layer it reaches, so a level round rod's middle layers get 4/pi
  // of their mean and a flat rod lying level its full width. What a ditherer working layer by layer holds.
  double layerVoxels = 0.0;
  // Peak while slicing with `bandsInFlight` bands alive (the caller's pipeline says how many: the
  // slicer's kBandsInFlight, slicer/job_pipeline.hpp), or while voxelizing the whole design
  // (bandsInFlight = 0). A band holds two grids of bandBytes each, its moduli and its fractions
  // (materials::mapToFractions: the same leaves), and the voxel::TreeRecyclers of the streaming
  // (tree_assembly.hpp: the rasterizer's and the slicer's for the fractions) keep `keptTrees` let-go
  // band trees in all (the sum of their keptTrees()), whose nodes the next bands are built from:
  // bandTreesHeld of them. Measured against the heap (tests/test_slicer_memory.cpp, 0 to 3 kept trees)
  // and the resident memory of `rodfab slice` (bench/README.md).
  double peakBytes(int bandsInFlight, std::size_t keptTrees) const;
  static double bandTreesHeld(int bandsInFlight, std::size_t keptTrees);
};
RasterEstimate estimateRaster(const geometry::RodStructure& structure, const PrinterGrid& grid, int bandLayers = 0);

// estimateRaster for many band sizes of one design (a slicer trying smaller bands under a small budget):
// the pass over the rods' polyline samples, the costly part (74 M instructions on the curved lattice, as
// much for every band size before), once, into a table of leaves a layer; then each band size in time
// linear in the layers. estimate(b) equals estimateRaster(structure, grid, b) exactly (b <= 0: the
// design's figures, no band). Holds a double a layer of the grid (std::bad_alloc if it cannot). The
// estimates are thread-safe (const).
class RasterProfile {
public:
  RasterProfile(const geometry::RodStructure& structure, const PrinterGrid& grid);
  // `withNextLayer`: the band's grids hold the layer past it too (error diffusion's), as estimateRaster's
  // do; false: a band of exactly its layers (the white and blue ditherers' fractions, every material grid).
  // Bands are assumed cut as slicer::bandEnd cuts them (whole slabs from a slab boundary, or 1, 2 or 4
  // layers within one slab): a band of 8 layers starting elsewhere touches two slabs, twice the leaves.
  RasterEstimate estimate(int bandLayers, bool withNextLayer = true) const;

private:
  PrinterGrid grid_;
  RasterEstimate whole_;                // the design's figures, no band
  double internalBytes_ = 0.0;          // the rods' internal nodes, before the envelope's cap
  std::vector<double> leavesPerLayer_;  // each rod's leaves spread over its layers (addRodToLayers)
  double layerVoxels_ = 0.0;            // RasterEstimate::layerVoxels
};

// A rod the printer may not reproduce: its section is thinner than a voxel in some direction, or it
// holds fewer voxels than its volume implies.
struct ThinRod {
  std::size_t rod = 0;          // index into structure.rods
  double thinnestMm = 0.0;      // the section's smaller dimension (mm)
  double expectedVoxels = 0.0;  // the rod's volume over the voxel volume
  std::uint64_t voxels = 0;     // active voxels it won (0 when no counts were given)
  std::string reason;           // one line naming the rod, for a warning
};
// Rods whose section's smaller dimension is below the largest voxel edge (depending on its direction
// such a rod falls between voxel centres: a 0.02 mm rod prints as a few isolated voxels), and, when
// `voxelsPerRod` (Rasterization::voxelsPerRod, indexed like the rods) is given, rods holding less than
// half the voxels their volume implies (thin, or mostly inside other rods). In rod order; each rod
// once. Throws std::invalid_argument when voxelsPerRod is neither empty nor one count per rod.
std::vector<ThinRod> findThinRods(const geometry::RodStructure& structure, const PrinterGrid& grid,
                                  const std::vector<std::uint64_t>& voxelsPerRod = {});

}  // namespace rodfab::voxel
