// Error diffusion's layer preparation (error_diffusion_layers.hpp): a layer's voxels enumerated from the
// band's leaves, their thresholds drawn, their neighbours linked. The sweep is error_diffusion.cpp.
#include "materials/error_diffusion_layers.hpp"

#include "common/cpu_clones.hpp"
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
RODFAB_CLONES("avx512f", "avx2", "default") void drawUniforms(std::uint64_t seed, const int* i, int j, int k, float* out,
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

namespace {

// A run: voxels [begin, end) of a row at consecutive x, the first at x.
struct Run {
  int x;
  std::uint32_t begin, end;
  int xEnd() const { return x + static_cast<int>(end - begin); }
};

// The runs of the row [begin, end) of `x` into `runs` (which only grows). x rises strictly along a row,
// so x[v + 8] - x[v] == 8 says that voxels v .. v + 8 are one run: a run is crossed 8 voxels a step,
// then its end found one voxel at a time within the last 8 (two mispredicted branches a run, where
// galloping and a binary search took several).
std::size_t findRuns(const int* x, std::uint32_t begin, std::uint32_t end, std::vector<Run>& runs) {
  if (runs.size() < end - begin) runs.resize(end - begin);
  std::size_t n = 0;
  for (std::uint32_t v = begin; v < end;) {
    std::uint32_t inside = v;
    while (inside + 8 < end && x[inside + 8] - x[inside] == 8) inside += 8;
    std::uint32_t past = inside + 1;
    while (past < end && x[past] == x[past - 1] + 1) ++past;
    runs[n++] = {x[v], v, past};
    v = past;
  }
  return n;
}

// The next-row Link bits of voxel x (kNextLeft, kNextSame, kNextRight for x - 1, x, x + 1) given the
// next row's runs [p, last) of which p is the first ending past x - 1.
unsigned nextRowBits(int x, const Run* p, const Run* last) {
  unsigned bits = 0;
  for (int d = -1; d <= 1; ++d) {
    while (p != last && p->xEnd() <= x + d) ++p;
    if (p != last && p->x <= x + d) bits |= kNextLeft << (d + 1);
  }
  return bits;
}

// Voxels [v, v + count): links `bits`, nextRow from `first` rising by `step` (0 or 1) a voxel. One loop
// per array: together they were not vectorized (a byte store may alias the indices).
void fillLinks(std::uint8_t* links, std::uint32_t* nextRow, std::uint32_t v, int count, unsigned bits,
               std::uint32_t first, std::uint32_t step) {
  std::fill_n(links + v, count, static_cast<std::uint8_t>(bits));
  std::uint32_t* out = nextRow + v;  // not nextRow[v + n]: a 32-bit index may wrap, which stops the vectorizer
  for (int n = 0; n < count; ++n) out[n] = first + step * static_cast<std::uint32_t>(n);
}

// The in-layer links of run c's voxels against the next row's runs [p, last) (p advanced here; nextEnd
// where the next row ends, 0 when there is none). The next row is piecewise constant along x: where its
// run covers x - 1 .. x + 1, or none touches them, a whole stretch of voxels is filled at once; the
// few voxels at a next run's edges are linked one by one.
void linkRun(const Run& c, const Run*& p, const Run* last, std::uint32_t nextEnd, std::uint8_t* links,
             std::uint32_t* nextRow) {
  constexpr unsigned kSides = kLeft | kRight, kAllNext = kNextLeft | kNextSame | kNextRight;
  for (int x = c.x; x < c.xEnd();) {
    while (p != last && p->xEnd() <= x - 1) ++p;
    const auto v = c.begin + static_cast<std::uint32_t>(x - c.x);
    int count = 1;
    if (p == last || p->x >= x + 2) {  // nothing at x - 1 .. x + 1
      count = (p == last ? c.xEnd() : std::min(c.xEnd(), p->x - 1)) - x;
      fillLinks(links, nextRow, v, count, kSides, p == last ? nextEnd : p->begin, 0);
    } else if (p->x <= x - 1 && p->xEnd() >= x + 2) {  // all three in run p
      count = std::min(c.xEnd(), p->xEnd() - 1) - x;
      fillLinks(links, nextRow, v, count, kSides | kAllNext, p->begin + static_cast<std::uint32_t>(x - 1 - p->x), 1);
    } else {
      const std::uint32_t first = p->begin + static_cast<std::uint32_t>(std::max(0, x - 1 - p->x));
      fillLinks(links, nextRow, v, 1, kSides | nextRowBits(x, p, last), first, 0);
    }
    x += count;
  }
  links[c.begin] &= static_cast<std::uint8_t>(~kLeft);
  links[c.end - 1] &= static_cast<std::uint8_t>(~kRight);
}

}  // namespace

// The in-layer Link bits and nextRow of every voxel, each row's runs merged with the next row's: the
// voxels come in runs (47 voxels on average on the lattice), so most are filled a stretch at a time.
// Callgrind on the lattice slab: 12 instructions a voxel, runs found included; 64 walking voxel by voxel.
void linkWithinLayer(Layer& layer) {
  const int* x = layer.i.data();
  const std::vector<LayerRow>& rows = layer.rows;
  std::vector<Run> here, next;
  std::size_t hereCount = rows.empty() ? 0 : findRuns(x, rows[0].begin, rows[0].end, here);
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const bool hasNext = r + 1 < rows.size() && rows[r + 1].j == rows[r].j + 1;
    const std::size_t nextCount = r + 1 < rows.size() ? findRuns(x, rows[r + 1].begin, rows[r + 1].end, next) : 0;
    const Run* p = next.data();
    const Run* last = p + (hasNext ? nextCount : 0);
    for (std::size_t c = 0; c < hereCount; ++c)
      linkRun(here[c], p, last, hasNext ? rows[r + 1].end : 0, layer.links.data(), layer.nextRow.data());
    std::swap(here, next);
    hereCount = nextCount;
  }
}

namespace {

// Run c's up links against the above row's runs [q, last) (q advanced here): overlaps take kUp and the
// voxel above, x by x; gaps kNoVoxel.
void linkRunUp(const Run& c, const Run*& q, const Run* last, std::uint8_t* links, std::uint32_t* up) {
  for (int x = c.x; x < c.xEnd();) {
    while (q != last && q->xEnd() <= x) ++q;
    const auto v = c.begin + static_cast<std::uint32_t>(x - c.x);
    const bool over = q != last && q->x <= x;
    const int count = (q == last ? c.xEnd() : std::min(c.xEnd(), over ? q->xEnd() : q->x)) - x;
    if (over) {
      const std::uint32_t a = q->begin + static_cast<std::uint32_t>(x - q->x);
      std::uint32_t* upOut = up + v;
      std::uint8_t* linksOut = links + v;
      for (int n = 0; n < count; ++n) upOut[n] = a + static_cast<std::uint32_t>(n);
      for (int n = 0; n < count; ++n) linksOut[n] = static_cast<std::uint8_t>(linksOut[n] | kUp);
    } else {
      std::fill_n(up + v, count, kNoVoxel);
    }
    x += count;
  }
}

}  // namespace

// Layer `below`'s up links (kUp and up[]) into `above`, the layer over it: rows of equal j, run by run
// (9 instructions a voxel on the lattice slab, where the walk voxel by voxel took 24).
void linkUp(Layer& below, const Layer& above) {
  std::vector<Run> runs, runsAbove;
  std::size_t ra = 0;
  for (const LayerRow& row : below.rows) {
    while (ra < above.rows.size() && above.rows[ra].j < row.j) ++ra;
    const bool hasAbove = ra < above.rows.size() && above.rows[ra].j == row.j;
    if (!hasAbove) {
      std::fill(below.up.begin() + row.begin, below.up.begin() + row.end, kNoVoxel);
      continue;
    }
    const std::size_t countAbove = findRuns(above.i.data(), above.rows[ra].begin, above.rows[ra].end, runsAbove);
    const std::size_t count = findRuns(below.i.data(), row.begin, row.end, runs);
    const Run* q = runsAbove.data();
    const Run* last = q + countAbove;
    for (std::size_t c = 0; c < count; ++c) linkRunUp(runs[c], q, last, below.links.data(), below.up.data());
  }
}

}  // namespace rodfab::materials::detail
