// Leaf-level plumbing shared by the ditherers: the leaves of a band of layers, their active voxels in
// the band, fraction checks and the assembly of the output grid. Internal to materials/.
#pragma once

#include <openvdb/openvdb.h>
#include <openvdb/tools/Prune.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <array>
#include <atomic>
#include <bit>
#include <cstdint>
#include <memory>
#include <vector>

namespace rodfab::materials::detail {

using FloatLeaf = openvdb::FloatTree::LeafNodeType;
using BoolLeaf = openvdb::BoolTree::LeafNodeType;
using LeafMask = FloatLeaf::NodeMaskType;

// Leaves holding any voxel of layers [k0, k1), sorted by origin (z, y, x), or in the tree's own order
// (as deterministic, and no sort) for work that does not care.
enum class LeafOrder { ZYX, Tree };
std::vector<const FloatLeaf*> leavesInLayers(const openvdb::FloatTree& tree, int k0, int k1,
                                             LeafOrder order = LeafOrder::ZYX);

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
  bool failed() const { return first_.load() != ~std::uint64_t{0}; }
  // Throws std::invalid_argument naming the grid, the voxel and its value.
  void throwIfFailed(const openvdb::FloatGrid& grid, const std::vector<const FloatLeaf*>& leaves) const;

private:
  std::atomic<std::uint64_t> first_{~std::uint64_t{0}};
};

// Throws FractionCheck's error for the first (in ZYX leaf order) active voxel of layers [k0, k1) that
// is not a fraction, if any: for work that ran on the leaves in tree order and found one.
void throwFirstInvalid(const openvdb::FloatGrid& fraction, int k0, int k1);

// A "material" grid with `like`'s transform holding `tree`.
openvdb::BoolGrid::Ptr materialGrid(openvdb::BoolTree::Ptr tree, const openvdb::FloatGrid& like);

// A "material" grid with `like`'s transform made of `leaves` (null entries skipped).
openvdb::BoolGrid::Ptr assembleMaterialGrid(std::vector<std::unique_ptr<BoolLeaf>>& leaves,
                                            const openvdb::FloatGrid& like);

// Bit b of the result is flags[b] (each 0 or 1): eight flags at a time, by the multiply that gathers
// the low bit of every byte into the top byte.
inline std::uint64_t packFlags(const std::array<std::uint8_t, 64>& flags) {
  std::uint64_t bits = 0;
  for (unsigned byte = 0; byte < 8; ++byte) {
    std::uint64_t eight = 0;  // flags 8 byte .. 8 byte + 7 in bytes 0 .. 7 (one load on little-endian)
    for (unsigned b = 0; b < 8; ++b) eight |= std::uint64_t{flags[8 * byte + b]} << (8 * b);
    bits |= ((eight * 0x0102040810204080ull) >> 56) << (8 * byte);
  }
  return bits;
}

// The bits of a leaf word's 64 values that are not a fraction (outside [0, 1] or NaN).
inline std::uint64_t invalidBits(const float* values) {
  bool allValid = true;  // a branch-free pass first (FractionCheck::valid with &): bad values are rare
  for (unsigned b = 0; b < 64; ++b) allValid &= (values[b] >= 0.0f) & (values[b] <= 1.0f);
  if (allValid) return 0;
  std::uint64_t bits = 0;
  for (unsigned b = 0; b < 64; ++b) bits |= static_cast<std::uint64_t>(!FractionCheck::valid(values[b])) << b;
  return bits;
}

// The Vero bits of leaf `in`'s voxels in `mask` by `rule` (see ditherPointwise); a voxel that is not a
// fraction goes to `check` as voxel `leafIndex` of the list.
template <typename Rule>
LeafMask ditherLeaf(const FloatLeaf& in, const LeafMask& mask, const Rule& rule, FractionCheck& check, std::size_t leafIndex) {
  std::array<std::uint8_t, 64> flags;
  const float* values = in.buffer().data();
  LeafMask vero;
  for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) {
    const std::uint64_t active = mask.template getWord<std::uint64_t>(w);
    if (!active) continue;
    if (const std::uint64_t bad = invalidBits(values + 64 * w) & active) {
      check.fail(leafIndex, w * 64 + static_cast<openvdb::Index>(std::countr_zero(bad)));
      continue;
    }
    rule(w, values + 64 * w, flags);
    vero.template getWord<std::uint64_t>(w) = packFlags(flags) & active;
  }
  return vero;
}

// Dithers layers [k0, k1) leaf by leaf in parallel, for rules that look at nothing but the voxel:
// ruleForLeaf(origin) returns the leaf's rule, called as rule(w, values, flags) for each leaf word w
// (offsets 64 w .. 64 w + 63, i.e. x = origin.x + w, y = origin.y + b / 8, z = origin.z + b % 8) that
// holds an active voxel; it sets flags[b] = 1 where values[b] makes Vero, for all 64 voxels, active or
// not (a loop without branches; inactive voxels are masked off after).
// When the band holds most of the grid's leaves (a whole grid, or a slicer's band grid), the output is
// the grid's topology copied in parallel, its leaves filled in place and the ones outside the band
// pruned: adding leaves one by one to a new tree took as long as dithering them, on one thread.
template <typename RuleForLeaf>
openvdb::BoolGrid::Ptr ditherPointwise(const openvdb::FloatGrid& fraction, int k0, int k1, const RuleForLeaf& ruleForLeaf) {
  std::vector<const FloatLeaf*> leaves = leavesInLayers(fraction.tree(), k0, k1, LeafOrder::Tree);
  const bool copyTopology = leaves.size() * 4 >= fraction.tree().leafCount() * 3;
  auto tree = copyTopology ? std::make_shared<openvdb::BoolTree>(fraction.tree(), false, openvdb::TopologyCopy())
                           : std::make_shared<openvdb::BoolTree>(false);
  std::vector<BoolLeaf*> copied;
  if (copyTopology) {
    leaves.clear();
    fraction.tree().getNodes(leaves);  // the same order as the copy's leaves: same topology
    tree->getNodes(copied);
  }
  std::vector<std::unique_ptr<BoolLeaf>> added(copyTopology ? 0 : leaves.size());
  FractionCheck check;
  std::atomic<bool> outsideBand{false};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves.size()), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t l = r.begin(); l != r.end(); ++l) {
      const FloatLeaf& in = *leaves[l];
      const LeafMask mask = activeInLayers(in, k0, k1);
      BoolLeaf* leaf = copyTopology ? copied[l] : nullptr;
      if (mask.isOff()) {
        if (leaf) {
          leaf->setValuesOff();
          outsideBand = true;
        }
        continue;
      }
      const LeafMask vero = ditherLeaf(in, mask, ruleForLeaf(in.origin()), check, l);
      if (!leaf) leaf = (added[l] = std::make_unique<BoolLeaf>(in.origin(), false, false)).get();
      leaf->setValueMask(mask);
      leaf->buffer() = BoolLeaf::Buffer(vero);
    }
  });
  if (check.failed()) throwFirstInvalid(fraction, k0, k1);
  if (outsideBand) openvdb::tools::pruneInactive(*tree);
  for (auto& leaf : added)
    if (leaf) tree->addLeaf(leaf.release());
  return materialGrid(tree, fraction);
}

}  // namespace rodfab::materials::detail
