#include "materials/error_diffusion.hpp"

#include "materials/band_leaves.hpp"
#include "materials/counter_hash.hpp"

#include <algorithm>
#include <array>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::materials {

namespace {

using detail::BoolLeaf;
using detail::FloatLeaf;

struct Voxel {
  int i;
  float fraction;
  std::uint32_t leaf;     // index into the band's leaves
  std::uint16_t offset;   // within that leaf
};
struct Row {
  int j;
  std::uint32_t begin, end;  // voxels [begin, end), ascending i
};
// One layer's active voxels in (j, i) order.
struct Layer {
  int k = 0;
  std::vector<Voxel> voxels;
  std::vector<Row> rows;
};

int floorToLeaf(int k) { return k & ~static_cast<int>(FloatLeaf::DIM - 1); }

// Leaves are sorted by origin (z, y, x), so a slab's leaves are contiguous and grouped by y.
Layer enumerateLayer(const std::vector<const FloatLeaf*>& leaves, int k) {
  Layer layer;
  layer.k = k;
  const int z0 = floorToLeaf(k);
  auto first = std::lower_bound(leaves.begin(), leaves.end(), z0,
                                [](const FloatLeaf* l, int z) { return l->origin().z() < z; });
  auto last = std::lower_bound(first, leaves.end(), z0 + 1,
                               [](const FloatLeaf* l, int z) { return l->origin().z() < z; });
  const openvdb::Index dz = static_cast<openvdb::Index>(k - z0);
  for (auto group = first; group != last;) {
    const int y0 = (*group)->origin().y();
    auto groupEnd = std::find_if(group, last, [y0](const FloatLeaf* l) { return l->origin().y() != y0; });
    for (openvdb::Index dy = 0; dy < FloatLeaf::DIM; ++dy) {
      const auto begin = static_cast<std::uint32_t>(layer.voxels.size());
      for (auto it = group; it != groupEnd; ++it) {
        const FloatLeaf& leaf = **it;
        const float* values = leaf.buffer().data();
        for (openvdb::Index dx = 0; dx < FloatLeaf::DIM; ++dx) {
          const openvdb::Index n = (dx << 6) | (dy << 3) | dz;
          if (!leaf.isValueOn(n)) continue;
          layer.voxels.push_back({leaf.origin().x() + static_cast<int>(dx), values[n],
                                  static_cast<std::uint32_t>(it - leaves.begin()), static_cast<std::uint16_t>(n)});
        }
      }
      const auto end = static_cast<std::uint32_t>(layer.voxels.size());
      if (end > begin) layer.rows.push_back({y0 + static_cast<int>(dy), begin, end});
    }
    group = groupEnd;
  }
  return layer;
}

// Voxel indices of one row by x, for O(1) neighbour lookups; filled for a row and cleared after.
class RowIndex {
public:
  RowIndex(int xBase, int width) : xBase_(xBase), slots_(static_cast<std::size_t>(std::max(width, 0)) + 2, -1) {}
  void fill(const Layer& layer, const Row& row) {
    for (std::uint32_t v = row.begin; v < row.end; ++v) slot(layer.voxels[v].i) = static_cast<std::int32_t>(v);
  }
  void clear(const Layer& layer, const Row& row) {
    for (std::uint32_t v = row.begin; v < row.end; ++v) slot(layer.voxels[v].i) = -1;
  }
  // -1 outside the part (or outside the band's x range).
  std::int32_t at(int i) const {
    const int s = i - xBase_ + 1;
    return s >= 0 && s < static_cast<int>(slots_.size()) ? slots_[s] : -1;
  }

private:
  std::int32_t& slot(int i) { return slots_[static_cast<std::size_t>(i - xBase_ + 1)]; }
  int xBase_;
  std::vector<std::int32_t> slots_;
};

// The previous band's error for `layer` (its first layer k0), matched by (j, i): both lists are in that
// order. Throws std::logic_error for an entry whose voxel is not in `layer` (the bands' grids disagree).
template <typename CarryList>
std::vector<float> errorFromCarry(const Layer& layer, const CarryList& carry) {
  std::vector<float> error(layer.voxels.size(), 0.0f);
  std::size_t r = 0, v = 0;
  for (const auto& c : carry) {
    while (r < layer.rows.size() && layer.rows[r].j < c.j) ++r;
    bool found = false;
    if (r < layer.rows.size() && layer.rows[r].j == c.j) {
      v = std::max<std::size_t>(v, layer.rows[r].begin);
      while (v < layer.rows[r].end && layer.voxels[v].i < c.i) ++v;
      found = v < layer.rows[r].end && layer.voxels[v].i == c.i;
    }
    if (!found)
      throw std::logic_error("error-diffusion: voxel (" + std::to_string(c.i) + ", " + std::to_string(c.j) + ", " +
                             std::to_string(layer.k) + ") was inside the part one layer past the previous band but "
                             "is not in this band's grid: consecutive bands' grids disagree");
    error[v] = c.error;
  }
  return error;
}

// Diffuses the error of one layer after another: serpentine rows, Floyd-Steinberg weights within the
// layer and kShareToNextLayer straight up, renormalized over the neighbours inside the part. Writes
// Vero voxels into `out` (one leaf per band leaf) and records invalid fractions in `check`.
class LayerDiffusion {
public:
  LayerDiffusion(int xMin, int xMax, std::uint64_t seed, std::vector<std::unique_ptr<BoolLeaf>>& out,
                 detail::FractionCheck& check)
      : nextRowIndex_(xMin, xMax - xMin + 1), aboveIndex_(xMin, xMax - xMin + 1), seed_(seed), out_(out), check_(check) {}

  // Dithers `layer` (layer k) with the error already on its voxels; returns the error it passes to `above`.
  std::vector<float> run(const Layer& layer, std::vector<float>& error, const Layer& above, int k) {
    std::vector<float> errorAbove(above.voxels.size(), 0.0f);
    std::size_t aboveRow = 0;
    for (std::size_t r = 0; r < layer.rows.size(); ++r) {
      const Row& row = layer.rows[r];
      const Row* nextRow = r + 1 < layer.rows.size() && layer.rows[r + 1].j == row.j + 1 ? &layer.rows[r + 1] : nullptr;
      while (aboveRow < above.rows.size() && above.rows[aboveRow].j < row.j) ++aboveRow;
      const Row* rowAbove = aboveRow < above.rows.size() && above.rows[aboveRow].j == row.j ? &above.rows[aboveRow] : nullptr;
      if (nextRow) nextRowIndex_.fill(layer, *nextRow);
      if (rowAbove) aboveIndex_.fill(above, *rowAbove);
      diffuseRow(layer, row, nextRow != nullptr, rowAbove != nullptr, k, error, errorAbove);
      if (nextRow) nextRowIndex_.clear(layer, *nextRow);
      if (rowAbove) aboveIndex_.clear(above, *rowAbove);
    }
    return errorAbove;
  }

private:
  static constexpr float kShareToNextLayer = ErrorDiffusionDitherer::kShareToNextLayer;
  static constexpr float kInLayer = 1.0f - kShareToNextLayer;
  // Floyd-Steinberg weights: ahead in the row, then behind / below / ahead in the next row.
  static constexpr std::array<float, 4> kWeights{7.0f / 16 * kInLayer, 3.0f / 16 * kInLayer, 5.0f / 16 * kInLayer,
                                                 1.0f / 16 * kInLayer};

  void diffuseRow(const Layer& layer, const Row& row, bool hasNextRow, bool hasRowAbove, int k, std::vector<float>& error,
                  std::vector<float>& errorAbove) {
    const int dir = ((row.j + k) & 1) ? -1 : +1;
    const auto count = static_cast<std::int64_t>(row.end - row.begin);
    for (std::int64_t step = 0; step < count; ++step) {
      const std::uint32_t v = dir > 0 ? row.begin + static_cast<std::uint32_t>(step)
                                      : row.end - 1 - static_cast<std::uint32_t>(step);
      const Voxel& voxel = layer.voxels[v];
      const float f = voxel.fraction;
      if (!detail::FractionCheck::valid(f)) {
        check_.fail(voxel.leaf, voxel.offset);
        continue;
      }
      const float wanted = f + error[v];
      const float threshold =
          0.5f + ErrorDiffusionDitherer::kThresholdJitter * (voxelUniform(seed_, voxel.i, row.j, k) - 0.5f);
      const bool vero = f >= 1.0f || (f > 0.0f && wanted >= threshold);
      if (vero) out_[voxel.leaf]->setValueOnly(voxel.offset, true);
      const float residual = wanted - (vero ? 1.0f : 0.0f);

      // Neighbours that are inside the part, with their weights; renormalized below.
      std::array<std::int32_t, 4> targets{-1, -1, -1, -1};
      if (step + 1 < count) {
        const std::uint32_t a = dir > 0 ? v + 1 : v - 1;
        if (layer.voxels[a].i == voxel.i + dir) targets[0] = static_cast<std::int32_t>(a);
      }
      if (hasNextRow) {
        targets[1] = nextRowIndex_.at(voxel.i - dir);
        targets[2] = nextRowIndex_.at(voxel.i);
        targets[3] = nextRowIndex_.at(voxel.i + dir);
      }
      const std::int32_t up = hasRowAbove ? aboveIndex_.at(voxel.i) : -1;
      float total = up >= 0 ? kShareToNextLayer : 0.0f;
      for (int t = 0; t < 4; ++t)
        if (targets[t] >= 0) total += kWeights[t];
      if (total <= 0.0f) continue;  // an isolated voxel with nothing after it: its error has nowhere to go
      const float scale = residual / total;
      for (int t = 0; t < 4; ++t)
        if (targets[t] >= 0) error[targets[t]] += kWeights[t] * scale;
      if (up >= 0) errorAbove[up] += kShareToNextLayer * scale;
    }
  }

  RowIndex nextRowIndex_, aboveIndex_;
  std::uint64_t seed_;
  std::vector<std::unique_ptr<BoolLeaf>>& out_;
  detail::FractionCheck& check_;
};

}  // namespace

openvdb::BoolGrid::Ptr ErrorDiffusionDitherer::ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) {
  if (started_ && k0 != nextLayer_)
    throw std::logic_error("error-diffusion: bands must follow each other: expected a band starting at layer " +
                           std::to_string(nextLayer_) + ", got " + std::to_string(k0) + " (reset() to start over)");
  // One layer past the band: its active voxels decide where the last layer's error may go.
  const std::vector<const FloatLeaf*> leaves = detail::leavesInLayers(fraction.tree(), k0, k1 + 1);
  std::vector<std::unique_ptr<BoolLeaf>> out(leaves.size());
  int xMin = 0, xMax = -1;
  for (std::size_t l = 0; l < leaves.size(); ++l) {
    const FloatLeaf& in = *leaves[l];
    xMin = l == 0 ? in.origin().x() : std::min(xMin, in.origin().x());
    xMax = l == 0 ? in.origin().x() + 7 : std::max(xMax, in.origin().x() + 7);
    const detail::LeafMask mask = detail::activeInLayers(in, k0, k1);
    if (mask.isOff()) continue;
    out[l] = std::make_unique<BoolLeaf>(in.origin(), false, false);
    out[l]->setValueMask(mask);
  }
  if (k0 == k1) return detail::assembleMaterialGrid(out, fraction);

  detail::FractionCheck check;
  LayerDiffusion diffusion(xMin, xMax, seed_, out, check);
  Layer layer = enumerateLayer(leaves, k0);
  std::vector<float> error = started_ ? errorFromCarry(layer, carry_) : std::vector<float>(layer.voxels.size(), 0.0f);
  for (int k = k0; k < k1; ++k) {
    Layer above = enumerateLayer(leaves, k + 1);
    std::vector<float> errorAbove = diffusion.run(layer, error, above, k);
    layer = std::move(above);
    error = std::move(errorAbove);
  }
  check.throwIfFailed(fraction, leaves);

  carry_.clear();
  for (const Row& row : layer.rows)
    for (std::uint32_t v = row.begin; v < row.end; ++v)
      if (error[v] != 0.0f) carry_.push_back({layer.voxels[v].i, row.j, error[v]});
  started_ = true;
  nextLayer_ = k1;
  return detail::assembleMaterialGrid(out, fraction);
}

}  // namespace rodfab::materials
