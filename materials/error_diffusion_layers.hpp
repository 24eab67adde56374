// Error diffusion's layer preparation: one layer's active voxels as arrays in (j, i) order (fraction,
// jittered threshold, output leaf and offset) with the neighbours inside the part worked out as bits
// and indices, so the sweep (error_diffusion.cpp) does no lookups. Internal to materials/.
#pragma once

#include "materials/band_leaves.hpp"

#include <cstdint>
#include <limits>
#include <vector>

namespace rodfab::materials::detail {

struct LayerRow {
  int j;
  std::uint32_t begin, end;  // voxels [begin, end), ascending i
};

// Which neighbours of a voxel are inside the part: bits of Layer::links, set when the layer is prepared
// (kUp when the layer above is), so the sweep itself does no lookups.
enum Link : std::uint8_t {
  kLeft = 1,        // (i - 1, j, k): voxel v - 1
  kRight = 2,       // (i + 1, j, k): voxel v + 1
  kNextLeft = 4,    // (i - 1, j + 1, k): voxel nextRow[v]
  kNextSame = 8,    // (i, j + 1, k): the next voxel of the next row
  kNextRight = 16,  // (i + 1, j + 1, k): the one after
  kUp = 32,         // (i, j, k + 1): voxel up[v] of the layer above
};
constexpr std::uint32_t kNoVoxel = std::numeric_limits<std::uint32_t>::max();

// Layer::resize grows an array past its capacity to n + n / kLayerHeadroom voxels (not the doubling of
// std::vector's growth): a slot's per-voxel arrays hold at most 9/8 of its fullest layer.
constexpr std::size_t kLayerHeadroom = 8;

// One layer's active voxels in (j, i) order, as arrays: the sweep reads them one after the other.
struct Layer {
  int k = 0;
  std::vector<LayerRow> rows;
  std::vector<int> i;
  std::vector<float> fraction;
  std::vector<float> threshold;        // the jittered threshold of each voxel
  std::vector<std::uint32_t> leaf;     // index into the band's leaves
  std::vector<std::uint16_t> offset;   // within that leaf
  std::vector<std::uint8_t> links;     // Link bits
  std::vector<std::uint32_t> nextRow;  // the first voxel of row j + 1 with x >= i - 1 (when it has one)
  std::vector<std::uint32_t> up;       // the voxel above, kNoVoxel if none
  std::vector<std::uint64_t> leafRows;  // scratch of enumerateLayer: each slab leaf's voxels in layer k
  std::size_t size() const { return i.size(); }
  // Every per-voxel array to n voxels (kLayerHeadroom past its capacity).
  void resize(std::size_t n);
};

// Fills `layer`'s rows and voxels (i, fraction, leaf, offset) for layer k of `leaves` (sorted by origin
// (z, y, x), as leavesInLayers gives them) in place: its vectors keep their capacity from the layer the
// slot held before (layers of millions of voxels otherwise cost a fresh allocation, its page faults and
// its growth copies each).
void enumerateLayer(const std::vector<const FloatLeaf*>& leaves, int k, Layer& layer);

// Each voxel's threshold: 0.5 jittered by +-jitter / 2 from its voxelUniform(seed, i, j, k).
void computeThresholds(std::uint64_t seed, float jitter, Layer& layer);

// The in-layer Link bits and nextRow of every voxel.
void linkWithinLayer(Layer& layer);

// Layer `below`'s up links (kUp and up[]) into `above`, the layer over it.
void linkUp(Layer& below, const Layer& above);

}  // namespace rodfab::materials::detail
