#include "voxel/diagnostics.hpp"

#include "voxel/memory_estimate.hpp"
#include "voxel/rod_pieces.hpp"
#include "voxel/tree_assembly.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <utility>
#include <vector>

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

// Bytes of one leaf of the modulus grid as allocated: the node, its separately allocated buffer of
// 512 values (not in sizeof: the node holds a pointer to it) and glibc's 16-byte header on each.
double leafBytes() {
  using Leaf = openvdb::FloatTree::LeafNodeType;
  return double(sizeof(Leaf)) + double(Leaf::SIZE * sizeof(Leaf::ValueType)) + 2.0 * 16.0;
}

// Layers a band's grids may hold: whole 8-layer leaf slabs, one more for the next layer error diffusion
// reads, and one more when the band is not whole slabs (its ends need not fall on slab boundaries).
double heldLayers(int bandLayers) { return std::ceil(bandLayers / 8.0) * 8.0 + (bandLayers % 8 == 0 ? 8.0 : 16.0); }

// Leaves (8^3 voxels, aligned to multiples of 8 in index space) a box of the envelope [0, dims)
// reaching `layers` layers can hold: however much the rods' widened tubes overlap (thin rods close
// together count the same leaves many times over), a tree holds no more.
double leavesSpanned(const PrinterGrid& grid, double layers) {
  const double up = std::min(std::ceil(grid.dims.z() / 8.0), std::ceil(std::max(0.0, layers - 1.0) / 8.0) + 1.0);
  return std::ceil(grid.dims.x() / 8.0) * std::ceil(grid.dims.y() / 8.0) * up;
}

// Bytes of the internal nodes (128^3 and 4096^3 voxels, aligned to multiples of their size in index
// space) that a box of the envelope [0, dims) reaching `layers` layers can touch: whatever the rods, a
// tree holds no internal node outside the box.
double internalBytesSpanned(const PrinterGrid& grid, double layers) {
  double bytes = 0.0;
  for (const auto& [dim, nodeBytes] : {std::pair{128.0, double(sizeof(Internal1))}, std::pair{4096.0, double(sizeof(Internal2))}}) {
    const double across = std::ceil(grid.dims.x() / dim) * std::ceil(grid.dims.y() / dim);
    const double up = std::min(std::ceil(grid.dims.z() / dim), std::ceil(std::max(0.0, layers - 1.0) / dim) + 1.0);
    bytes += across * up * nodeBytes;
  }
  return bytes;
}

// Nodes of `dim`^3 voxels the rod touches at most: its solid widened by half a node's diagonal, over
// the node's volume, plus one.
double nodesTouched(const PrinterGrid& grid, int dim, const geometry::Rod& rod) {
  const openvdb::Vec3d node = grid.voxelSize * double(dim);
  return widenedRodVolume(rod, 0.5 * node.length()) / (node.x() * node.y() * node.z()) + 1.0;
}

// Adds `leaves` of the rod to `perLayer` (the envelope's layers): spread over the layers its polyline
// segments reach, in proportion to their lengths, each over its z range widened by what its section,
// caps and half a leaf reach in z (so the leaves of a level stretch land in its few layers).
void spreadOverLayers(const geometry::Rod& rod, double leaves, const PrinterGrid& grid, std::vector<double>& perLayer) {
  const std::vector<double>& u = rod.sampleParameters();
  const double caps = rod.caps() == geometry::CapStyle::Round ? rod.section().capRadius() : 0.0;
  const double halfLeaf = 4.0 * grid.voxelSize.z(), last = double(perLayer.size() - 1);
  const auto layer = [&](double z) { return std::clamp((z - grid.origin.z()) / grid.voxelSize.z(), 0.0, last); };
  std::vector<double> added(perLayer.size() + 1, 0.0);  // differences: perLayer[k] += sum of added[0..k]
  for (std::size_t i = 0; i + 1 < u.size(); ++i) {
    const geometry::Vec3 a = rod.centerline().point(u[i]), b = rod.centerline().point(u[i + 1]);
    const double length = (b - a).norm(), share = leaves * length / std::max(rod.length(), 1e-12);
    const double upness = length > 0.0 ? std::abs(b.z() - a.z()) / length : 1.0;
    const double reach = rod.section().boundingRadius() * std::sqrt(std::max(0.0, 1.0 - upness * upness)) + caps + halfLeaf;
    const auto k0 = std::size_t(std::floor(layer(std::min(a.z(), b.z()) - reach)));
    const auto k1 = std::size_t(std::ceil(layer(std::max(a.z(), b.z()) + reach)));
    added[k0] += share / double(k1 - k0 + 1);
    added[k1 + 1] -= share / double(k1 - k0 + 1);
  }
  double running = 0.0;
  for (std::size_t k = 0; k < perLayer.size(); ++k) perLayer[k] += running += added[k];
}

// The most of `perLayer` any `window` consecutive layers hold.
double fullestWindow(const std::vector<double>& perLayer, double window) {
  const std::size_t w = std::min(perLayer.size(), std::size_t(std::max(1.0, window)));
  double sum = 0.0, most = 0.0;
  for (std::size_t k = 0; k < perLayer.size(); ++k) {
    sum += perLayer[k] - (k >= w ? perLayer[k - w] : 0.0);
    most = std::max(most, sum);
  }
  return most;
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

double RasterEstimate::bytesPerPiece() { return double(sizeof(detail::RodPiece) + sizeof(detail::AffineInIndex)); }

double RasterEstimate::peakBytes(int bandsInFlight) const {
  return pieceBytes + (bandsInFlight > 0 ? bandTreesHeld(bandsInFlight) * bandBytes : gridBytes);
}

RasterEstimate estimateRaster(const geometry::RodStructure& structure, const PrinterGrid& grid, int bandLayers) {
  RasterEstimate e;
  double internalBytes = 0.0;
  std::vector<double> leavesPerLayer(bandLayers > 0 ? std::size_t(std::max(1, grid.dims.z())) : 0, 0.0);
  std::vector<double> voxelsPerLayer(leavesPerLayer.size(), 0.0);
  for (const geometry::Rod& rod : structure.rods) {
    const std::uint64_t pieces = detail::pieceBudget(rod, grid);
    e.maxPieces += pieces;
    e.pieceBytes += double(pieces) * RasterEstimate::bytesPerPiece();
    e.activeVoxels += rodVolume(rod) / grid.voxelVolume();
    const double leaves = nodesTouched(grid, 8, rod);
    e.leaves += leaves;
    internalBytes += nodesTouched(grid, 128, rod) * double(sizeof(Internal1)) + nodesTouched(grid, 4096, rod) * double(sizeof(Internal2));
    if (bandLayers > 0) {
      spreadOverLayers(rod, leaves, grid, leavesPerLayer);
      spreadOverLayers(rod, rodVolume(rod) / grid.voxelVolume(), grid, voxelsPerLayer);
    }
  }
  // Rods close together share internal nodes: no more than the envelope (or a band of it) spans.
  e.leaves = std::min(e.leaves, leavesSpanned(grid, grid.dims.z()));
  e.gridBytes = e.leaves * leafBytes() + std::min(internalBytes, internalBytesSpanned(grid, grid.dims.z()));
  if (bandLayers > 0) {
    e.bandLeaves = std::min({fullestWindow(leavesPerLayer, heldLayers(bandLayers)), e.leaves,
                             leavesSpanned(grid, heldLayers(bandLayers))});
    e.layerVoxels = std::min(fullestWindow(voxelsPerLayer, 1.0), double(grid.dims.x()) * double(grid.dims.y()));
    e.bandBytes = std::min(e.bandLeaves * leafBytes() + std::min(internalBytes, internalBytesSpanned(grid, heldLayers(bandLayers))),
                           e.gridBytes);
  }
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
