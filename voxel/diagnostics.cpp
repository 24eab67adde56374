#include "voxel/diagnostics.hpp"

#include "voxel/rod_pieces.hpp"
#include "voxel/tree_assembly.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

namespace rodfab::voxel {

namespace {

// A rod's volume (mm^3): swept section plus, with round caps, a ball per smooth piece (its two halves).
double rodVolume(const geometry::Rod& rod) {
  double volume = rod.section().area() * rod.length();
  if (rod.caps() == geometry::CapStyle::Round) {
    const double r = rod.section().capRadius();
    volume += double(rod.smoothPieces().size()) * 4.0 / 3.0 * std::numbers::pi * r * r * r;
  }
  return volume;
}

using Internal2 = openvdb::FloatTree::RootNodeType::ChildNodeType;  // 4096^3 voxels
using Internal1 = Internal2::ChildNodeType;                             // 128^3 voxels

// Bytes of one leaf of the modulus grid as allocated (with the allocator's share).
double leafBytes() { return double(sizeof(openvdb::FloatTree::LeafNodeType)) + 64.0; }

// Nodes of `dim`^3 voxels a tube of radius r (mm) and length `length` touches: the tube widened by half
// a node's diagonal all round, over the node's volume, plus one.
double nodesTouched(const PrinterGrid& grid, int dim, double r, double length) {
  const openvdb::Vec3d node = grid.voxelSize * double(dim);
  const double wide = r + 0.5 * node.length();
  return std::numbers::pi * wide * wide * (length + 2.0 * wide) / (node.x() * node.y() * node.z()) + 1.0;
}

std::string format(const char* pattern, double a, double b = 0.0) {
  char text[160];
  std::snprintf(text, sizeof text, pattern, a, b);
  return text;
}

}  // namespace

int RasterEstimate::bandTreesHeld(int bandsInFlight) {
  constexpr int kGridsPerBand = 2;  // moduli and fractions
  constexpr int kRecyclers = 2;     // the rasterizer's modulus trees, the slicer's fraction trees
  return kGridsPerBand * bandsInFlight + kRecyclers * int(TreeRecycler<openvdb::FloatTree>::kKeptTrees);
}

double RasterEstimate::peakBytes(int bandsInFlight) const {
  return pieceBytes + (bandsInFlight > 0 ? bandTreesHeld(bandsInFlight) * bandBytes : gridBytes);
}

RasterEstimate estimateRaster(const geometry::RodStructure& structure, const PrinterGrid& grid, int bandLayers) {
  RasterEstimate e;
  double internalBytes = 0.0;
  for (const geometry::Rod& rod : structure.rods) {
    const std::uint64_t pieces = detail::pieceBudget(rod, grid);
    e.maxPieces += pieces;
    e.pieceBytes += double(pieces) * double(sizeof(detail::RodPiece) + sizeof(detail::AffineInIndex));
    e.activeVoxels += rodVolume(rod) / grid.voxelVolume();
    // The nodes touched by the rod as a tube of its bounding radius (the internal nodes of rods close
    // together are shared: an upper estimate).
    const double r = rod.section().boundingRadius();
    const double leaves = nodesTouched(grid, 8, r, rod.length());
    e.leaves += leaves;
    internalBytes += nodesTouched(grid, 128, r, rod.length()) * double(sizeof(Internal1)) +
                     nodesTouched(grid, 4096, r, rod.length()) * double(sizeof(Internal2));
    if (bandLayers > 0) {
      const double layers = std::max(1.0, rod.bounds().sizes().z() / grid.voxelSize.z());
      e.bandBytes += leaves * std::min(1.0, (bandLayers + 16.0) / layers) * leafBytes();
    }
  }
  e.gridBytes = e.leaves * leafBytes() + internalBytes;
  if (bandLayers > 0) e.bandBytes = std::min(e.bandBytes + internalBytes, e.gridBytes);
  return e;
}

std::vector<ThinRod> findThinRods(const geometry::RodStructure& structure, const PrinterGrid& grid,
                                  const std::vector<std::uint64_t>& voxelsPerRod) {
  if (!voxelsPerRod.empty() && voxelsPerRod.size() != structure.rods.size())
    throw std::invalid_argument("findThinRods: expected one voxel count per rod (" + std::to_string(structure.rods.size()) +
                                "), got " + std::to_string(voxelsPerRod.size()));
  const double coarsest = std::max({grid.voxelSize.x(), grid.voxelSize.y(), grid.voxelSize.z()});
  std::vector<ThinRod> out;
  for (std::size_t r = 0; r < structure.rods.size(); ++r) {
    const geometry::Rod& rod = structure.rods[r];
    ThinRod t;
    t.rod = r;
    t.thinnestMm = std::min(rod.section().width, rod.section().height);
    t.expectedVoxels = rodVolume(rod) / grid.voxelVolume();
    t.voxels = voxelsPerRod.empty() ? 0 : voxelsPerRod[r];
    const std::string name = "rod " + std::to_string(r) + " ('" + rod.name() + "')";
    if (t.thinnestMm < coarsest) {
      t.reason = name + format(": its section is %.4g mm thin, below the printer's voxel (%.4g mm in its coarsest direction)",
                               t.thinnestMm, coarsest) +
                 (voxelsPerRod.empty() ? std::string() : "; it holds " + std::to_string(t.voxels) + " voxels") +
                 ": it may print as isolated voxels or not at all";
    } else if (!voxelsPerRod.empty() && double(t.voxels) < 0.5 * t.expectedVoxels) {
      t.reason = name + ": it holds " + std::to_string(t.voxels) + format(" voxels where its volume implies about %.0f", t.expectedVoxels) +
                 " (thinner than the voxels resolve, or mostly inside other rods)";
    } else {
      continue;
    }
    out.push_back(std::move(t));
  }
  return out;
}

}  // namespace rodfab::voxel
