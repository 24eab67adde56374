#include "voxel/diagnostics.hpp"

#include "voxel/memory_estimate.hpp"
#include "voxel/rod_pieces.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
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

// Layers a band's grids may hold: the whole 8-layer leaf slabs its layers, and the next one when
// `withNextLayer` (error diffusion reads it), touch, for bands cut as slicer::bandEnd cuts them: bands
// of whole slabs start on a slab boundary and touch bandLayers / 8 slabs, bands of 1, 2 or 4 layers stay
// within one slab, one more slab with the next layer either way; n consecutive layers anywhere touch at
// most ceil((n - 1) / 8) + 1. Without the next layer a slicer's white and blue bands hold half the slabs
// the estimate counted before (the lattice's band grids: 10,412 leaves, not 20,800).
double heldLayers(int bandLayers, bool withNextLayer) {
  const int next = withNextLayer ? 1 : 0;
  if (bandLayers % 8 == 0) return double(bandLayers + 8 * next);
  if (8 % bandLayers == 0) return double(8 + 8 * next);
  return (std::ceil((bandLayers + next - 1) / 8.0) + 1.0) * 8.0;
}

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

// Internal nodes of `dim`^3 voxels the rod touches at most: its solid widened by half a node's
// diagonal, over the node's volume, plus one (the leaves are counted piece by piece: leafCounts).
double nodesTouched(const PrinterGrid& grid, int dim, const geometry::Rod& rod) {
  const openvdb::Vec3d node = grid.voxelSize * double(dim);
  return widenedRodVolume(rod, 0.5 * node.length()) / (node.x() * node.y() * node.z()) + 1.0;
}

// Sums over the envelope's layers of values added over ranges of z, as differences and one prefix sum
// at the end (two vectors for the whole design, whatever the number of rods). Ranges are in layer units
// (layer k spans [k - 1/2, k + 1/2)), clipped to the envelope; a layer partly in a range gets that part
// of the value, so ranges that meet (consecutive segments of a rod) add up to one value, not two.
class LayerProfile {
public:
  explicit LayerProfile(std::size_t layers) : differences_(layers + 1, 0.0) {}

  // Adds `perLayer` to the layers of [lo, hi].
  void add(double lo, double hi, double perLayer) {
    clip(lo, hi);
    const std::size_t first = layerAt(lo), last = layerAt(hi);
    if (first == last) {
      addTo(first, first, perLayer * (hi - lo));
      return;
    }
    addTo(first, first, perLayer * (double(first) + 0.5 - lo));
    if (first + 1 < last) addTo(first + 1, last - 1, perLayer);
    addTo(last, last, perLayer * (hi - (double(last) - 0.5)));
  }
  // Spreads `total` evenly over the part of [lo, hi] inside the envelope (all of it on one layer when
  // that part is under a layer thick): the layers always get the whole total.
  void spread(double lo, double hi, double total) {
    clip(lo, hi);
    if (hi - lo >= 1.0) return add(lo, hi, total / (hi - lo));
    const std::size_t middle = layerAt(0.5 * (lo + hi));
    addTo(middle, middle, total);
  }
  // The value of every layer.
  std::vector<double> layers() const {
    std::vector<double> out(differences_.size() - 1);
    double running = 0.0;
    for (std::size_t k = 0; k < out.size(); ++k) out[k] = running += differences_[k];
    return out;
  }

private:
  void clip(double& lo, double& hi) const {
    const double top = double(differences_.size() - 1) - 0.5;
    lo = std::clamp(lo, -0.5, top);
    hi = std::clamp(hi, lo, top);
  }
  std::size_t layerAt(double z) const { return std::min(std::size_t(std::floor(z + 0.5)), differences_.size() - 2); }
  void addTo(std::size_t first, std::size_t last, double value) {
    differences_[first] += value;
    differences_[last + 1] -= value;
  }
  std::vector<double> differences_;
};

// How a rod's section lies across z at one sample: the z components a, b of its frame's d1 and d2 (the
// section's width and height directions) give its half-extent in z, and a layer through it (a plane of
// constant z) cuts the section along lines perpendicular to (a, b) in the section's plane, the longest
// of them through its centre (the sections are convex and centrally symmetric).
struct SectionAcrossZ {
  geometry::Frame frame;    // the rod's frame there (d1, d2: the section's width and height directions)
  double halfHeight = 0.0;  // mm above and below the centre line
  double tilt = 0.0;        // |(a, b)|: 1 for a level rod, 0 where the rod runs straight up
  double chord = 0.0;       // the longest line a layer cuts through the section (0 for an upright one)
  // The most section a layer through a straight piece of rod holds per mm of its length: the longest
  // such line, widened by `margin` at both ends, over the tilt (infinite for an upright section).
  double layerWidth = std::numeric_limits<double>::infinity();
};

SectionAcrossZ sectionAcrossZ(const geometry::Rod& rod, double u, double margin) {
  const geometry::Section& s = rod.section();
  SectionAcrossZ out;
  out.frame = rod.frame().at(rod.centerline(), u);
  const double a = out.frame.d1.z(), b = out.frame.d2.z();
  out.tilt = std::hypot(a, b);
  const bool rectangle = s.shape == geometry::SectionShape::Rectangle;
  out.halfHeight = rectangle ? 0.5 * (std::abs(a) * s.width + std::abs(b) * s.height) : 0.5 * std::hypot(a * s.width, b * s.height);
  if (out.tilt < 1e-12) return out;
  const double m1 = -b / out.tilt, m2 = a / out.tilt;  // the line's direction in the section's plane
  const double inf = std::numeric_limits<double>::infinity();
  const double chord = rectangle ? std::min(m1 != 0.0 ? s.width / std::abs(m1) : inf, m2 != 0.0 ? s.height / std::abs(m2) : inf)
                                 : 1.0 / std::hypot(m1 / s.width, m2 / s.height);
  out.chord = chord;
  out.layerWidth = (chord + 2.0 * margin) / out.tilt;
  return out;
}

// The most section a layer through a straight segment holds per mm of its length, from the frames at
// its ends. At a corner the frame is the next segment's (the tangent after the knot), so an end whose
// tilt is not the segment's own (sqrt(1 - (rise / length)^2): d1, d2 and the tangent are orthonormal)
// is not used: a level segment ending where the rod turns upright would otherwise take the upright
// frame's infinite width. With neither end usable, the section's widest chord, `fallbackWidth`.
double segmentLayerWidth(const SectionAcrossZ& before, const SectionAcrossZ& after, double length, double rise, double fallbackWidth) {
  const double slope = length > 0.0 ? std::min(1.0, rise / length) : 0.0;
  const double tilt = std::sqrt(1.0 - slope * slope);
  // Smooth rods change tilt far less between samples; a corner that changes it by more (from level: 41
  // degrees) is seen, a smaller one overstates the width by at most 1 / 0.75.
  constexpr double kOwnTilt = 0.25;
  double width = 0.0;
  for (const SectionAcrossZ* end : {&before, &after})
    if (std::abs(end->tilt - tilt) <= kOwnTilt) width = std::max(width, end->layerWidth);
  if (width > 0.0) return width;
  return tilt > 1e-12 ? fallbackWidth / tilt : std::numeric_limits<double>::infinity();
}

// The section's width along v (its extent in the direction of v, times |v|) as the frame holds it.
double sectionWidthAlong(const geometry::Section& s, const geometry::Frame& frame, const geometry::Vec3& v) {
  const double p = v.dot(frame.d1), q = v.dot(frame.d2);
  return s.shape == geometry::SectionShape::Rectangle ? s.width * std::abs(p) + s.height * std::abs(q) : std::hypot(s.width * p, s.height * q);
}

// Leaves (8^3 voxels) a straight piece of rod touches, expected over where the lattice of leaves falls:
// a leaf touches the solid exactly when its centre lies in the solid widened by a leaf's box (their
// Minkowski sum), so the count is that sum's volume over a leaf's. For a section S swept a length l
// along the unit tangent t (S plus four segments: the sweep and the box's edges, 2 a_i along e_i):
//   l [area(S) + sum_i 2 a_i w(t x e_i) + sum_{i<j} 4 a_i a_j |t_k|]          perLength, times l
//   + sum_i 2 a_i area(S) |t_i| + sum_{i<j} 4 a_i a_j w(e_k) + 8 a_x a_y a_z   atEnds, once a rod
// (w(v): the section's width along v, sectionWidthAlong). A ball of half the leaf's diagonal in place
// of the box (nodesTouched, as the leaves were counted before) counts 1.3 to 1.5 times as many on the
// lattices' rods (leaves of 0.34 x 0.68 x 0.24 mm on the Connex3). The larger of the counts with the
// frames at the piece's two ends.
struct LeafCounts {
  double perLength = 0.0;  // leaves a mm of the piece
  double atEnds = 0.0;     // leaves the rod's two ends add
};
LeafCounts leafCounts(const geometry::Section& s, const SectionAcrossZ& before, const SectionAcrossZ& after,
                      const geometry::Vec3& tangent, const PrinterGrid& grid) {
  const geometry::Vec3 half = 4.0 * geometry::Vec3(grid.voxelSize.x(), grid.voxelSize.y(), grid.voxelSize.z());
  const double volume = 8.0 * half.x() * half.y() * half.z();
  LeafCounts most;
  for (const SectionAcrossZ* end : {&before, &after}) {
    // The layers get these leaves spread evenly over the section's height (addRodToLayers), which the
    // slab through a level rod's middle only gets if every layer holds as much of the section as the
    // widest: its longest cut times its height in place of its area (4 / pi of a round section's).
    const double area = std::max(s.area(), end->chord * 2.0 * end->halfHeight);
    LeafCounts c{area, 8.0 * half.x() * half.y() * half.z()};
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3, k = (i + 2) % 3;  // the pair (j, k) and the axis i across it
      const geometry::Vec3 axis = geometry::Vec3::Unit(i);
      c.perLength += 2.0 * half[i] * sectionWidthAlong(s, end->frame, tangent.cross(axis)) + 4.0 * half[j] * half[k] * std::abs(tangent[i]);
      c.atEnds += 2.0 * half[i] * area * std::abs(tangent[i]) + 4.0 * half[j] * half[k] * sectionWidthAlong(s, end->frame, axis);
    }
    most.perLength = std::max(most.perLength, c.perLength / volume);
    most.atEnds = std::max(most.atEnds, c.atEnds / volume);
  }
  return most;
}

// Adds the rod to the layers, segment by segment of its polyline (each straight, its section as the
// frame holds it at the segment's ends). Leaves: each segment's (leafCounts) spread evenly over the
// layers its section, caps and half a leaf reach, and each end's share around it; returns the rod's
// leaves, the sum of those shares. Voxels: the most a layer through the segment can hold, in every
// layer it reaches: its length times the section a layer cuts (both widened by half a voxel's diagonal
// for the lattice's rounding), and no more than its length times the section's area over its rise (a
// steep segment's layers share its volume): a level round rod's middle layers get their 4/pi of the
// mean, a flat one lying level its full width in its few layers.
double addRodToLayers(const geometry::Rod& rod, const PrinterGrid& grid, LayerProfile& leavesPerLayer,
                      LayerProfile& voxelsPerLayer) {
  const std::vector<double>& u = rod.sampleParameters();
  if (u.size() < 2) return 0.0;
  const geometry::Section& section = rod.section();
  const double caps = rod.caps() == geometry::CapStyle::Round ? section.capRadius() : 0.0;
  const double vz = grid.voxelSize.z(), halfLeaf = 4.0 * vz;
  const double margin = 0.5 * std::hypot(grid.voxelSize.x(), grid.voxelSize.y());
  const double widenedArea = section.area() + section.perimeter() * margin + std::numbers::pi * margin * margin;
  const double voxelArea = grid.voxelSize.x() * grid.voxelSize.y();
  // The rod's length widened by the margin at both ends, shared by its segments (a row of voxel centres
  // along it holds up to one more than its length in voxels).
  const double lengthScale = (rod.length() + 2.0 * margin) / std::max(rod.length(), 1e-12);
  const auto layer = [&](double z) { return (z - grid.origin.z()) / vz; };
  const double fallbackWidth = 2.0 * (section.boundingRadius() + margin);
  // Round caps: a half disc beyond each end, in the layers the cap reaches.
  for (const double end : {u.front(), u.back()})
    if (caps > 0.0) {
      const double z = rod.centerline().point(end).z();
      voxelsPerLayer.add(layer(z - caps - 0.5 * vz), layer(z + caps + 0.5 * vz), 0.5 * std::numbers::pi * (caps + margin) * (caps + margin) / voxelArea);
    }
  SectionAcrossZ before = sectionAcrossZ(rod, u[0], margin);
  geometry::Vec3 a = rod.centerline().point(u[0]);
  double leaves = 0.0;
  for (std::size_t i = 1; i < u.size(); ++i) {
    const geometry::Vec3 b = rod.centerline().point(u[i]);
    const SectionAcrossZ after = sectionAcrossZ(rod, u[i], margin);
    const double length = (b - a).norm(), rise = std::abs(b.z() - a.z());
    const double zLow = std::min(a.z(), b.z()), zHigh = std::max(a.z(), b.z());
    // Half a voxel more where the section spans layers (not along an upright one: consecutive segments meet there).
    const double reach = std::max({before.halfHeight, after.halfHeight, caps}) + 0.5 * vz * std::max(before.tilt, after.tilt);
    const double leavesLow = layer(zLow - reach - halfLeaf), leavesHigh = layer(zHigh + reach + halfLeaf);
    if (length > 0.0) {
      const LeafCounts counts = leafCounts(section, before, after, (b - a) / length, grid);
      // Each end of the rod: half the ends' leaves, its cap as more length (a round cap lies within the
      // section swept on by its radius), and half a leaf for the rounding, in the layers around the end.
      const double endLeaves = 0.5 * counts.atEnds + caps * counts.perLength + 0.5;
      const auto addEnd = [&](double z) {
        leavesPerLayer.spread(layer(z - reach - halfLeaf), layer(z + reach + halfLeaf), endLeaves);
        leaves += endLeaves;
      };
      if (i == 1) addEnd(a.z());
      if (i + 1 == u.size()) addEnd(b.z());
      leavesPerLayer.spread(leavesLow, leavesHigh, length * counts.perLength);
      leaves += length * counts.perLength;
    }
    const double width = std::min(segmentLayerWidth(before, after, length, rise, fallbackWidth), widenedArea / std::max(rise, 1e-12));
    voxelsPerLayer.add(layer(zLow - reach), layer(zHigh + reach), lengthScale * length * width / voxelArea);
    before = after;
    a = b;
  }
  return leaves;
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

double RasterEstimate::bandTreesHeld(int bandsInFlight, std::size_t keptTrees) {
  constexpr int kGridsPerBand = 2;  // moduli and fractions
  return kGridsPerBand * bandsInFlight + double(keptTrees);
}

double RasterEstimate::bytesPerPiece() { return double(sizeof(detail::RodPiece) + sizeof(detail::AffineInIndex)); }

double RasterEstimate::peakBytes(int bandsInFlight, std::size_t keptTrees) const {
  return pieceBytes + (bandsInFlight > 0 ? bandTreesHeld(bandsInFlight, keptTrees) * bandBytes : gridBytes);
}

namespace {

// The design's figures, no band (RasterEstimate's whole-design fields), and its rods' internal-node bytes
// before the envelope's cap; each rod added to `leavesPerLayer` and `voxelsPerLayer` (its leaves the sum
// of what it adds there).
RasterEstimate designTotals(const geometry::RodStructure& structure, const PrinterGrid& grid, double& internalBytes,
                            LayerProfile& leavesPerLayer, LayerProfile& voxelsPerLayer) {
  RasterEstimate e;
  internalBytes = 0.0;
  for (const geometry::Rod& rod : structure.rods) {
    const std::uint64_t pieces = detail::pieceBudget(rod, grid);
    e.maxPieces += pieces;
    e.pieceBytes += double(pieces) * RasterEstimate::bytesPerPiece();
    e.activeVoxels += rodVolume(rod) / grid.voxelVolume();
    internalBytes += nodesTouched(grid, 128, rod) * double(sizeof(Internal1)) + nodesTouched(grid, 4096, rod) * double(sizeof(Internal2));
    e.leaves += addRodToLayers(rod, grid, leavesPerLayer, voxelsPerLayer);
  }
  // Rods close together share internal nodes: no more than the envelope (or a band of it) spans.
  e.leaves = std::min(e.leaves, leavesSpanned(grid, grid.dims.z()));
  e.gridBytes = e.leaves * leafBytes() + std::min(internalBytes, internalBytesSpanned(grid, grid.dims.z()));
  return e;
}

}  // namespace

RasterProfile::RasterProfile(const geometry::RodStructure& structure, const PrinterGrid& grid) : grid_(grid) {
  const std::size_t layers = std::size_t(std::max(1, grid.dims.z()));
  LayerProfile leavesPerLayer(layers), voxelsPerLayer(layers);
  whole_ = designTotals(structure, grid, internalBytes_, leavesPerLayer, voxelsPerLayer);
  leavesPerLayer_ = leavesPerLayer.layers();
  layerVoxels_ = std::min(fullestWindow(voxelsPerLayer.layers(), 1.0), double(grid.dims.x()) * double(grid.dims.y()));
}

RasterEstimate RasterProfile::estimate(int bandLayers, bool withNextLayer) const {
  RasterEstimate e = whole_;
  if (bandLayers <= 0) return e;
  const double held = heldLayers(bandLayers, withNextLayer);
  e.bandLeaves = std::min({fullestWindow(leavesPerLayer_, held), e.leaves, leavesSpanned(grid_, held)});
  e.layerVoxels = layerVoxels_;
  e.bandBytes = std::min(e.bandLeaves * leafBytes() + std::min(internalBytes_, internalBytesSpanned(grid_, held)), e.gridBytes);
  return e;
}

RasterEstimate estimateRaster(const geometry::RodStructure& structure, const PrinterGrid& grid, int bandLayers) {
  return RasterProfile(structure, grid).estimate(bandLayers);
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
