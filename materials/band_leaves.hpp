// Leaf-level plumbing shared by the ditherers: the leaves of a band of layers, their active voxels in
// the band, fraction checks and the assembly of the output grid. Internal to materials/.
#pragma once

#include <openvdb/openvdb.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <bit>
#include <cstdint>
#include <memory>
#include <vector>

namespace rodfab::materials::detail {

using FloatLeaf = openvdb::FloatTree::LeafNodeType;
using BoolLeaf = openvdb::BoolTree::LeafNodeType;
using LeafMask = FloatLeaf::NodeMaskType;

// Leaves holding any voxel of layers [k0, k1), sorted by origin (z, y, x).
std::vector<const FloatLeaf*> leavesInLayers(const openvdb::FloatTree& tree, int k0, int k1);

// The leaf's active voxels that lie in layers [k0, k1).
LeafMask activeInLayers(const FloatLeaf& leaf, int k0, int k1);

// Records the first (in leaf order) voxel whose fraction is outside [0, 1]; safe to call from many
// threads, and the reported voxel does not depend on which thread saw what first.
class FractionCheck {
public:
  static bool valid(float f) { return f >= 0.0f && f <= 1.0f; }  // false for NaN
  void fail(std::size_t leafIndex, openvdb::Index offset) {
    const std::uint64_t position = leafIndex * FloatLeaf::SIZE + offset;  // in leaf order
    std::uint64_t seen = first_.load(std::memory_order_relaxed);
    while (position < seen && !first_.compare_exchange_weak(seen, position, std::memory_order_relaxed)) {
    }
  }
  // Throws std::invalid_argument naming the grid, the voxel and its value.
  void throwIfFailed(const openvdb::FloatGrid& grid, const std::vector<const FloatLeaf*>& leaves) const;

private:
  std::atomic<std::uint64_t> first_{~std::uint64_t{0}};
};

// A "material" grid with `like`'s transform made of `leaves` (null entries skipped).
openvdb::BoolGrid::Ptr assembleMaterialGrid(std::vector<std::unique_ptr<BoolLeaf>>& leaves,
                                            const openvdb::FloatGrid& like);

// Dithers layers [k0, k1) leaf by leaf in parallel, for rules that look at nothing but the voxel:
// ruleForLeaf(origin) returns the leaf's rule isVero(Index offset, float fraction) -> bool.
template <typename RuleForLeaf>
openvdb::BoolGrid::Ptr ditherPointwise(const openvdb::FloatGrid& fraction, int k0, int k1, const RuleForLeaf& ruleForLeaf) {
  const std::vector<const FloatLeaf*> leaves = leavesInLayers(fraction.tree(), k0, k1);
  std::vector<std::unique_ptr<BoolLeaf>> out(leaves.size());
  FractionCheck check;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves.size()), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t l = r.begin(); l != r.end(); ++l) {
      const FloatLeaf& in = *leaves[l];
      const LeafMask mask = activeInLayers(in, k0, k1);
      if (mask.isOff()) continue;
      auto leaf = std::make_unique<BoolLeaf>(in.origin(), false, false);
      leaf->setValueMask(mask);
      const float* values = in.buffer().data();
      const auto isVero = ruleForLeaf(in.origin());
      // Word by word over the active bits; the value bits are collected and stored in one go.
      LeafMask vero;
      for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) {
        std::uint64_t active = mask.template getWord<std::uint64_t>(w), bits = 0;
        while (active) {
          const int b = std::countr_zero(active);
          active &= active - 1;
          const openvdb::Index n = w * 64 + static_cast<openvdb::Index>(b);
          const float f = values[n];
          if (!FractionCheck::valid(f)) {
            check.fail(l, n);
            continue;
          }
          bits |= static_cast<std::uint64_t>(isVero(n, f)) << b;
        }
        vero.template getWord<std::uint64_t>(w) = bits;
      }
      leaf->buffer() = BoolLeaf::Buffer(vero);
      out[l] = std::move(leaf);
    }
  });
  check.throwIfFailed(fraction, leaves);
  return assembleMaterialGrid(out, fraction);
}

}  // namespace rodfab::materials::detail
