// Error diffusion's layer preparation (error_diffusion_layers.hpp): a layer's voxels enumerated from the
// band's leaves, their thresholds drawn, their neighbours linked. The sweep is error_diffusion.cpp.
#include "materials/error_diffusion_layers.hpp"

#include "materials/counter_hash.hpp"

#include <algorithm>
#include <bit>
#include <utility>

namespace rodfab::materials::detail {

namespace {

// Resizes `v` to n elements; past its capacity it reserves n + n / 8 (kLayerHeadroom), where resize()
// alone may double it: a slot's arrays then stay within 9/8 of the fullest layer they held, which is what
// ErrorDiffusionDitherer::workingBytes counts, and layers growing a little at a time still reallocate
// only once in an eighth of growth.
template <class T>
void resizeWithHeadroom(std::vector<T>& v, std::size_t n) {
  if (n > v.capacity()) v.reserve(n + n / kLayerHeadroom);
  v.resize(n);
}

}  // namespace

void Layer::resize(std::size_t n) {
  resizeWithHeadroom(i, n);
  resizeWithHeadroom(fraction, n);
  resizeWithHeadroom(threshold, n);
  resizeWithHeadroom(leaf, n);
  resizeWithHeadroom(offset, n);
  resizeWithHeadroom(links, n);
  resizeWithHeadroom(nextRow, n);
  resizeWithHeadroom(up, n);
}

namespace {

// How far ahead (in leaves) enumerateLayer asks for the values it will read: a leaf's row takes tens of
// cycles, a line from memory hundreds.
constexpr std::size_t kPrefetchLeaves = 16;

int floorToLeaf(int k) { return k & ~static_cast<int>(FloatLeaf::DIM - 1); }

// The leaves of `leaves` (sorted by origin (z, y, x)) in the slab holding layer k: contiguous, grouped by y.
std::pair<std::size_t, std::size_t> slabOf(const std::vector<const FloatLeaf*>& leaves, int k) {
  const int z0 = floorToLeaf(k);
  auto first = std::lower_bound(leaves.begin(), leaves.end(), z0,
                                [](const FloatLeaf* l, int z) { return l->origin().z() < z; });
  auto last = std::lower_bound(first, leaves.end(), z0 + 1,
                               [](const FloatLeaf* l, int z) { return l->origin().z() < z; });
  return {static_cast<std::size_t>(first - leaves.begin()), static_cast<std::size_t>(last - leaves.begin())};
}

// A leaf's active voxels in its layer dz as one word: bit 8 y + x for voxel (x, y, dz) (in the mask,
// word x holds bit 8 y + z). Eight shifts and masks instead of a test per voxel.
std::uint64_t layerRows(const LeafMask& mask, unsigned dz) {
  constexpr std::uint64_t kLowBitOfEachByte = 0x0101010101010101ull;
  std::uint64_t rows = 0;
  for (unsigned dx = 0; dx < FloatLeaf::DIM; ++dx)
    rows |= ((mask.template getWord<std::uint64_t>(dx) >> dz) & kLowBitOfEachByte) << dx;
  return rows;
}

// Asks for the cache lines of `leaf`'s values that hold its voxels in layer dz (`rows` from layerRows):
// the voxels of one layer are spread over all of a leaf's lines, and the enumeration stalled on them.
void prefetchLayer(const FloatLeaf& leaf, std::uint64_t rows, unsigned dz) {
  const float* values = leaf.buffer().data();
  // Voxels (x, y) and (x, y + 1), y even, share a line of 16 floats: one request per such pair.
  for (std::uint64_t pairs = (rows | rows >> 8) & 0x00ff00ff00ff00ffull; pairs; pairs &= pairs - 1) {
    const auto bit = static_cast<unsigned>(std::countr_zero(pairs));  // 8 y + x
    __builtin_prefetch(values + ((bit & 7u) << 6) + ((bit >> 3) << 3) + dz);
  }
}

// The Philox draw of each voxel of a row as a uniform number (voxelUniform), in one loop the compiler
// vectorizes: the draws were a third of the sweep's time. Integer arithmetic and an exact conversion,
// so every clone gives the same numbers; no throw in a target_clones function (GCC 12 assumes none).
[[gnu::target_clones("avx512f", "avx2", "default")]] void drawUniforms(std::uint64_t seed, const int* i, int j, int k, float* out,
                                                          std::uint32_t count) noexcept {
  for (std::uint32_t v = 0; v < count; ++v) out[v] = voxelUniform(seed, i[v], j, k);
}

}  // namespace

// Fills `layer`'s rows and voxels (i, fraction, leaf, offset) in place: its vectors keep their capacity
// from the layer the slot held before (layers of millions of voxels otherwise cost a fresh allocation,
// its page faults and its growth copies each). Each leaf's voxels in the layer are gathered into one
// word first (layerRows), which also gives the count, so each array is sized once and the voxels are
// then visited bit by bit, with no test (and no mispredicted branch) per inactive voxel.
void enumerateLayer(const std::vector<const FloatLeaf*>& leaves, int k, Layer& layer) {
  layer.k = k;
  layer.rows.clear();
  const auto [first, last] = slabOf(leaves, k);
  const auto dz = static_cast<unsigned>(k - floorToLeaf(k));
  layer.leafRows.resize(last - first);
  std::size_t count = 0;
  for (std::size_t l = first; l != last; ++l) {
    if (l + kPrefetchLeaves < last) __builtin_prefetch(&leaves[l + kPrefetchLeaves]->getValueMask());
    const std::uint64_t rows = layerRows(leaves[l]->getValueMask(), dz);
    layer.leafRows[l - first] = rows;
    count += static_cast<std::size_t>(std::popcount(rows));
  }
  layer.resize(count);
  for (std::size_t l = first; l != std::min(last, first + kPrefetchLeaves); ++l) prefetchLayer(*leaves[l], layer.leafRows[l - first], dz);
  std::uint32_t n = 0;
  for (std::size_t group = first; group != last;) {
    const int y0 = leaves[group]->origin().y();
    std::size_t groupEnd = group;
    while (groupEnd != last && leaves[groupEnd]->origin().y() == y0) ++groupEnd;
    for (unsigned dy = 0; dy < FloatLeaf::DIM; ++dy) {
      const std::uint32_t begin = n;
      for (std::size_t l = group; l != groupEnd; ++l) {
        // On the first pass over the group, the leaves a little ahead (of this group or the next).
        if (dy == 0 && l + kPrefetchLeaves < last) prefetchLayer(*leaves[l + kPrefetchLeaves], layer.leafRows[l + kPrefetchLeaves - first], dz);
        const unsigned row = static_cast<unsigned>(layer.leafRows[l - first] >> (8 * dy)) & 0xffu;
        if (!row) continue;
        const FloatLeaf& leaf = *leaves[l];
        const float* values = leaf.buffer().data();
        for (unsigned xs = row; xs; xs &= xs - 1) {
          const auto dx = static_cast<unsigned>(std::countr_zero(xs));
          const auto offset = static_cast<std::uint16_t>((dx << 6) | (dy << 3) | dz);
          layer.i[n] = leaf.origin().x() + static_cast<int>(dx);
          layer.fraction[n] = values[offset];
          layer.leaf[n] = static_cast<std::uint32_t>(l);
          layer.offset[n] = offset;
          ++n;
        }
      }
      if (n > begin) layer.rows.push_back({y0 + static_cast<int>(dy), begin, n});
    }
    group = groupEnd;
  }
}

// Each voxel's threshold: 0.5 jittered by +-kThresholdJitter / 2 from its uniform number.
void computeThresholds(std::uint64_t seed, float jitter, Layer& layer) {
  for (const LayerRow& row : layer.rows)
    drawUniforms(seed, layer.i.data() + row.begin, row.j, layer.k, layer.threshold.data() + row.begin, row.end - row.begin);
  for (float& t : layer.threshold) t = 0.5f + jitter * (t - 0.5f);
}

// The in-layer Link bits and nextRow of every voxel, walking each row alongside the next. Through raw
// pointers: a byte store (links) may alias anything, and the vectors' pointers were reloaded after each.
void linkWithinLayer(Layer& layer) {
  const int* x = layer.i.data();
  std::uint8_t* links = layer.links.data();
  std::uint32_t* nextRow = layer.nextRow.data();
  const std::vector<LayerRow>& rows = layer.rows;
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const LayerRow row = rows[r];
    const bool hasNext = r + 1 < rows.size() && rows[r + 1].j == row.j + 1;
    const std::uint32_t nextEnd = hasNext ? rows[r + 1].end : 0;
    std::uint32_t n = hasNext ? rows[r + 1].begin : 0;
    for (std::uint32_t v = row.begin; v < row.end; ++v) {
      const int xv = x[v];
      unsigned bits = 0;
      if (v > row.begin && x[v - 1] == xv - 1) bits |= kLeft;
      if (v + 1 < row.end && x[v + 1] == xv + 1) bits |= kRight;
      while (n < nextEnd && x[n] < xv - 1) ++n;
      std::uint32_t m = n;
      if (m < nextEnd && x[m] == xv - 1) bits |= kNextLeft, ++m;
      if (m < nextEnd && x[m] == xv) bits |= kNextSame, ++m;
      if (m < nextEnd && x[m] == xv + 1) bits |= kNextRight;
      links[v] = static_cast<std::uint8_t>(bits);
      nextRow[v] = n;
    }
  }
}

// Layer `below`'s up links (kUp and up[]) into `above`, the layer over it, walking rows of equal j.
void linkUp(Layer& below, const Layer& above) {
  const int* x = below.i.data();
  const int* xAbove = above.i.data();
  std::uint8_t* links = below.links.data();
  std::uint32_t* up = below.up.data();
  std::size_t ra = 0;
  for (const LayerRow& row : below.rows) {
    while (ra < above.rows.size() && above.rows[ra].j < row.j) ++ra;
    const bool hasAbove = ra < above.rows.size() && above.rows[ra].j == row.j;
    std::uint32_t a = hasAbove ? above.rows[ra].begin : 0;
    const std::uint32_t aEnd = hasAbove ? above.rows[ra].end : 0;
    for (std::uint32_t v = row.begin; v < row.end; ++v) {
      while (a < aEnd && xAbove[a] < x[v]) ++a;
      const bool found = a < aEnd && xAbove[a] == x[v];
      up[v] = found ? a : kNoVoxel;
      links[v] = static_cast<std::uint8_t>(links[v] | (found ? unsigned{kUp} : 0u));
    }
  }
}

}  // namespace rodfab::materials::detail
