// Leaf-level plumbing shared by the ditherers: the leaves of a band of layers, their active voxels in
// the band, fraction checks and the assembly of the output grid. Internal to materials/.
#pragma once

#include "materials/fraction_map.hpp"
#include "voxel/tree_assembly.hpp"

#include <openvdb/openvdb.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <array>
#include <atomic>
#include <bit>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
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

// The leaves of leavesInLayers (tree order) grouped by their parent node (128^3 voxels): parent p holds
// leaves[begin[p]] .. leaves[begin[p + 1] - 1], so an output tree can be assembled parent by parent.
struct LeafGroups {
  std::vector<const FloatLeaf*> leaves;
  std::vector<std::size_t> begin{0};  // one more than the parents
  std::size_t parentCount() const { return begin.size() - 1; }
};
LeafGroups leafGroupsInLayers(const openvdb::FloatTree& tree, int k0, int k1);

// The leaf's active voxels that lie in layers [k0, k1).
LeafMask activeInLayers(const FloatLeaf& leaf, int k0, int k1);

// A leaf mask's eight 64-bit words, as FractionMap::mapWords takes them.
inline std::array<std::uint64_t, 8> maskWords(const LeafMask& mask) {
  static_assert(LeafMask::WORD_COUNT == 8);
  std::array<std::uint64_t, 8> words;
  for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) words[w] = mask.template getWord<std::uint64_t>(w);
  return words;
}

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

// Nodes taken from an output tree its owners let go of, to build the next one from
// (voxel/tree_assembly.hpp).
using SpareNodes = voxel::SpareNodes<openvdb::BoolTree>;

// The output trees of earlier bands come back here when their last owner (the slicer's writer) lets
// them go, and the next band's tree is built from their nodes (voxel::TreeRecycler): a slicer streaming
// thousands of bands then allocates its output leaves and internal nodes for the first bands only,
// instead of once per band (malloc, zeroing the 32 KB node tables and page faults on fresh memory cost
// as much as the dithering arithmetic on the lattice class).
class OutputTreeRecycler : public voxel::TreeRecycler<openvdb::BoolTree> {
public:
  OutputTreeRecycler() : voxel::TreeRecycler<openvdb::BoolTree>(false) {}
  // A tree with the leaves `leaves` (null entries skipped; grouped by parent as in `groups`), its
  // internal nodes taken from `spares` where there are any, that returns here when its owners let go.
  openvdb::BoolTree::Ptr assemble(const LeafGroups& groups, std::vector<std::unique_ptr<BoolLeaf>>& leaves,
                                  SpareNodes& spares) const;
};

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

// The words of a leaf's 512 Vero bits, word w = offsets 64 w .. 64 w + 63.
using LeafWords = std::array<std::uint64_t, LeafMask::WORD_COUNT>;

// The Vero bits of leaf `in`'s voxels in `mask` by `rule` (see ditherPointwise); a voxel that is not a
// fraction goes to `check` as voxel `leafIndex` of the list.
template <typename Rule>
LeafMask ditherLeaf(const FloatLeaf& in, const LeafMask& mask, const Rule& rule, FractionCheck& check, std::size_t leafIndex) {
  const float* values = in.buffer().data();
  unsigned words = 0;  // bit w: word w has active voxels, all of them fractions
  for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) {
    const std::uint64_t active = mask.template getWord<std::uint64_t>(w);
    if (!active) continue;
    if (const std::uint64_t bad = invalidBits(values + 64 * w) & active) {
      check.fail(leafIndex, w * 64 + static_cast<openvdb::Index>(std::countr_zero(bad)));
      continue;
    }
    words |= 1u << w;
  }
  LeafWords bits{};
  if (words) rule(values, words, bits);
  LeafMask vero;
  for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w)
    vero.template getWord<std::uint64_t>(w) = (words >> w & 1u) ? bits[w] & mask.template getWord<std::uint64_t>(w) : 0;
  return vero;
}

// The walk both pointwise paths share: the leaves of `tree` holding voxels of layers [k0, k1), in
// parallel, each leaf's Vero bits from veroOf(in, mask, l) (`mask`: its active voxels in the band, not
// empty; `l`: its index in the band's leaf list, tree order) into an output leaf with that mask; then
// afterLeaves() on the calling thread (it may throw: nothing is assembled yet), then the output tree,
// its leaves and internal nodes taken from `recycler`'s spares where it has any (earlier bands'
// outputs), that goes back to the recycler when its owners let go. `checkInterrupt`, when set, is
// called before each leaf (DitherOptions::checkInterrupt); what it throws leaves the call.
template <typename VeroOfLeaf, typename AfterLeaves>
openvdb::BoolTree::Ptr ditherLeavesInLayers(const openvdb::FloatTree& tree, int k0, int k1, const VeroOfLeaf& veroOf,
                                            const AfterLeaves& afterLeaves, OutputTreeRecycler& recycler,
                                            const std::function<void()>& checkInterrupt) {
  const LeafGroups groups = leafGroupsInLayers(tree, k0, k1);
  SpareNodes spares = recycler.takeSpares();
  std::vector<std::unique_ptr<BoolLeaf>> out(groups.leaves.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, groups.leaves.size()), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t l = r.begin(); l != r.end(); ++l) {
      if (checkInterrupt) checkInterrupt();
      const FloatLeaf& in = *groups.leaves[l];
      const LeafMask mask = activeInLayers(in, k0, k1);
      if (mask.isOff()) continue;
      const LeafMask vero = veroOf(in, mask, l);
      out[l] = spares.leaf(l, in.origin());
      out[l]->setValueMask(mask);
      out[l]->buffer() = BoolLeaf::Buffer(vero);
    }
  });
  afterLeaves();
  return recycler.assemble(groups, out, spares);
}

// Dithers layers [k0, k1) of a fraction grid leaf by leaf in parallel, for rules that look at nothing
// but the voxel: ruleForLeaf(origin) returns the leaf's rule, called once a leaf as rule(values, words,
// bits): for each word w whose bit is set in `words` (offsets 64 w + b, i.e. x = origin.x + w, y =
// origin.y + b / 8, z = origin.z + b % 8, holding active voxels) it sets bit b of bits[w] where
// values[64 w + b] makes Vero, for all 64 voxels, active or not (loops without branches; inactive voxels
// are masked off after), and reads no other word of `values`. Output nodes and interrupts as
// ditherLeavesInLayers. Throws std::invalid_argument for an active voxel that is not a fraction.
template <typename RuleForLeaf>
openvdb::BoolGrid::Ptr ditherPointwise(const openvdb::FloatGrid& fraction, int k0, int k1, const RuleForLeaf& ruleForLeaf,
                                       OutputTreeRecycler& recycler, const std::function<void()>& checkInterrupt = {}) {
  FractionCheck check;
  const auto veroOf = [&](const FloatLeaf& in, const LeafMask& mask, std::size_t l) {
    return ditherLeaf(in, mask, ruleForLeaf(in.origin()), check, l);
  };
  const auto afterLeaves = [&] {
    if (check.failed()) throwFirstInvalid(fraction, k0, k1);
  };
  return materialGrid(ditherLeavesInLayers(fraction.tree(), k0, k1, veroOf, afterLeaves, recycler, checkInterrupt), fraction);
}

// The same without reuse: a fresh tree for every call.
template <typename RuleForLeaf>
openvdb::BoolGrid::Ptr ditherPointwise(const openvdb::FloatGrid& fraction, int k0, int k1, const RuleForLeaf& ruleForLeaf) {
  OutputTreeRecycler fresh;
  return ditherPointwise(fraction, k0, k1, ruleForLeaf, fresh);
}

// The Vero bits of leaf `in`'s voxels in `mask` (moduli, MPa) by `rule` applied to their fractions,
// which FractionMap::mapWords writes into `fractions` (the caller's 512 floats, in L1: never a leaf of
// a tree) just before; counts the leaf's voxels and clamps into `stats`. The fractions are mapWord's,
// as mapToFractions stores them, so the bits are those of dithering the mapped grid; no fraction
// check: a FractionMap gives values in [0, 1] only.
template <typename Rule>
LeafMask mapAndDitherLeaf(const FloatLeaf& in, const LeafMask& mask, const FractionMap& map, const Rule& rule,
                          float* fractions, MappingStats& stats) {
  const std::array<std::uint64_t, 8> active = maskWords(mask);
  const FractionMap::WordClamps clamps = map.mapWords(in.buffer().data(), active.data(), active.size(), fractions);
  stats.voxels += mask.countOn();
  stats.clamps.belowFloor += clamps.belowFloor;
  stats.clamps.aboveMax += clamps.aboveMax;
  unsigned words = 0;  // bit w: word w has active voxels
  for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) words |= (active[w] != 0 ? 1u : 0u) << w;
  LeafWords bits{};
  if (words) rule(fractions, words, bits);
  LeafMask vero;
  for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) vero.template getWord<std::uint64_t>(w) = bits[w] & active[w];
  return vero;
}

// Maps and dithers layers [k0, k1) of a modulus grid (active voxels in leaves only) in one pass over
// its leaves, for the rules of ditherPointwise: the same output as ditherPointwise on
// mapToFractions(modulus, map, k0, k1) (the same leaves, values and bits), and the same counts added
// to `stats`, without the fraction grid. The counts are summed per thread and added after the last
// leaf (integer sums: the same for any thread count); `stats` is left unchanged when something throws.
template <typename RuleForLeaf>
openvdb::BoolGrid::Ptr mapAndDitherPointwise(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                             const RuleForLeaf& ruleForLeaf, OutputTreeRecycler& recycler,
                                             const std::function<void()>& checkInterrupt, MappingStats& stats) {
  tbb::enumerable_thread_specific<MappingStats> counts;
  const auto veroOf = [&](const FloatLeaf& in, const LeafMask& mask, std::size_t) {
    alignas(64) float fractions[FloatLeaf::SIZE];
    return mapAndDitherLeaf(in, mask, map, ruleForLeaf(in.origin()), fractions, counts.local());
  };
  openvdb::BoolTree::Ptr tree = ditherLeavesInLayers(modulus.tree(), k0, k1, veroOf, [] {}, recycler, checkInterrupt);
  for (const MappingStats& s : counts) {
    stats.voxels += s.voxels;
    stats.clamps += s.clamps;
  }
  return materialGrid(std::move(tree), modulus);
}

}  // namespace rodfab::materials::detail
