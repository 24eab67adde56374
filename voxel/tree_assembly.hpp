// Assembly of an OpenVDB tree from leaves built elsewhere (in parallel), parent by parent.
//
// The rasterizer, the modulus-to-fraction mapping and the ditherers each build a band's leaves in
// parallel and then need them in a tree. Adding them one by one (Tree::addLeaf) walks from the root for
// every leaf on one thread; assembleTree instead fills the leaf parents (internal nodes of 128^3
// voxels) in parallel, each from its own leaves, then hangs the few upper nodes (4096^3) and the
// parents under the root on the calling thread. The result is the same tree as adding the leaves one
// by one to an empty tree: every internal node it creates holds the tree's background, inactive.
//
// For the standard 5-4-3 trees (openvdb::FloatTree, openvdb::BoolTree, ...), as in OpenVDB's tools:
//
//   template <typename TreeT, typename ForEachLeaf, typename NodeSource>
//   void assembleTree(TreeT& tree, std::size_t groupCount, const ForEachLeaf& forEachLeaf, NodeSource& nodes);
//
//   tree         an empty tree (no child of the root); receives every leaf handed over.
//   groupCount   how many groups the leaves come in; all the leaves of a group share one leaf parent
//                (a group may be empty, and several groups must not share a parent).
//   forEachLeaf  forEachLeaf(g, visit) calls visit(std::unique_ptr<LeafT>&) for each leaf slot of group
//                g, in a fixed order; null slots are skipped, the others are released into the tree.
//                Called once per group, concurrently for different groups.
//   nodes        where the internal nodes come from: FreshNodes below (new nodes), or any type with
//                  std::unique_ptr<ParentT> parent(std::size_t g, const openvdb::Coord& origin);
//                  std::unique_ptr<UpperT> upper(std::size_t u, const openvdb::Coord& origin);
//                returning an empty node at `origin` (no child, every tile the tree's background and
//                inactive), e.g. one kept from an earlier tree. parent() is called at most once per
//                group g, concurrently for different g; upper() on the calling thread, for u = 0, 1, ...
//                in the order the upper nodes are first needed.
//
// Errors: std::logic_error if a leaf lies outside its group's parent, if two leaves of a group share an
// origin, or if two groups share a parent (each would silently drop voxels); the tree then holds what
// was added before, and the leaves not yet handed over stay with their slots. std::bad_alloc and
// whatever forEachLeaf or `nodes` throw pass through the same way.
//
// Threads: runs in the caller's TBB arena (tbb::parallel_for over the groups). The tree's shape and
// contents do not depend on the thread count, and neither do the indices passed to `nodes`.
//
// Streaming band after band, the nodes of the trees already let go of can be reused (TreeRecycler,
// below): a band's leaves and internal nodes are then allocated for the first bands only, instead of
// once per band (malloc, filling and page-faulting fresh nodes cost as much as the arithmetic on some
// classes). SpareNodes is the node source of a recycled tree.
#pragma once

#include <openvdb/openvdb.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::voxel {

// The internal node that holds a tree's leaves (128^3 voxels in a 5-4-3 tree) and the one above it.
template <typename TreeT>
using LeafParentOf = typename TreeT::RootNodeType::ChildNodeType::ChildNodeType;
template <typename TreeT>
using UpperNodeOf = typename TreeT::RootNodeType::ChildNodeType;

// A node source that makes every node anew, holding `background`, inactive.
template <typename TreeT>
struct FreshNodes {
  typename TreeT::ValueType background;
  std::unique_ptr<LeafParentOf<TreeT>> parent(std::size_t, const openvdb::Coord& origin) const {
    return std::make_unique<LeafParentOf<TreeT>>(origin, background, false);
  }
  std::unique_ptr<UpperNodeOf<TreeT>> upper(std::size_t, const openvdb::Coord& origin) const {
    return std::make_unique<UpperNodeOf<TreeT>>(origin, background, false);
  }
};

namespace detail {
inline std::string coordText(const openvdb::Coord& c) {
  return "(" + std::to_string(c.x()) + ", " + std::to_string(c.y()) + ", " + std::to_string(c.z()) + ")";
}
// Hands `child` over to `node`, which must cover its origin and hold no child there yet: InternalNode::
// addChild would leak a child outside the node and delete one already in place (voxels lost unseen).
template <typename NodeT, typename ChildT>
void addOnce(NodeT& node, std::unique_ptr<ChildT>& child) {
  const openvdb::Coord origin = child->origin();
  const bool inside = (origin & ~(NodeT::DIM - 1)) == node.origin();
  if (!inside || node.isChildMaskOn(NodeT::coordToOffset(origin)))
    throw std::logic_error("assembleTree: a node at " + coordText(origin) +
                           (inside ? " was handed over twice" : " lies outside its parent at " + coordText(node.origin())));
  node.addChild(child.release());
}
}  // namespace detail

template <typename TreeT, typename ForEachLeaf, typename NodeSource>
void assembleTree(TreeT& tree, std::size_t groupCount, const ForEachLeaf& forEachLeaf, NodeSource& nodes) {
  using LeafT = typename TreeT::LeafNodeType;
  using ParentT = LeafParentOf<TreeT>;
  using UpperT = UpperNodeOf<TreeT>;
  std::vector<std::unique_ptr<ParentT>> parents(groupCount);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, groupCount), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t g = range.begin(); g != range.end(); ++g)
      forEachLeaf(g, [&](std::unique_ptr<LeafT>& leaf) {
        if (!leaf) return;
        if (!parents[g]) parents[g] = nodes.parent(g, leaf->origin() & ~(ParentT::DIM - 1));
        detail::addOnce(*parents[g], leaf);
      });
  });
  std::vector<UpperT*> uppers;  // owned by the tree; a job has a handful
  for (std::unique_ptr<ParentT>& parent : parents) {
    if (!parent) continue;
    const openvdb::Coord origin = parent->origin() & ~(UpperT::DIM - 1);
    auto upper = std::find_if(uppers.begin(), uppers.end(), [&](const UpperT* u) { return u->origin() == origin; });
    if (upper == uppers.end()) {
      std::unique_ptr<UpperT> node = nodes.upper(uppers.size(), origin);
      upper = uppers.insert(uppers.end(), node.get());
      tree.root().addChild(node.get());
      node.release();  // the tree's now
    }
    detail::addOnce(**upper, parent);
  }
}

// Runs f() on the calling thread in a TBB task group context of its own, isolated from the caller's, and
// rethrows what f throws. Let go of trees through it wherever the caller's context may be cancelling:
// in a stage of a tbb::parallel_pipeline, or a body of a parallel loop, after another one threw. There
// every parallel algorithm is cancelled before it starts, and OpenVDB frees a tree's nodes in one
// (Tree::clear, from ~Tree): the tree would come back empty with all its nodes leaked, silently
// (0.3-0.6 MB a failed slice of a small test job; found by the sanitizer build). Other OpenVDB calls
// that work in parallel skip their work there too, but a failing pipeline throws their results away:
// letting go is what needs this.
template <typename F>
void outsideCancellation(const F& f) {
  tbb::task_group_context own(tbb::task_group_context::isolated);
  tbb::task_group group(own);
  group.run_and_wait(f);
}

template <typename TreeT>
class TreeRecycler;

// Nodes taken from a tree its owners let go of (TreeRecycler::takeSpares), to build the next one from.
// Each spare is handed out by index, so threads can take different ones without a lock; the ones not
// taken are deleted with the SpareNodes. A node source of assembleTree.
template <typename TreeT>
class SpareNodes {
public:
  using LeafT = typename TreeT::LeafNodeType;
  using ParentT = LeafParentOf<TreeT>;
  using UpperT = UpperNodeOf<TreeT>;
  SpareNodes() = default;
  SpareNodes(SpareNodes&&) = default;
  SpareNodes& operator=(SpareNodes&&) = delete;
  ~SpareNodes() {
    deleteAll(leaves_);
    deleteAll(parents_);
    deleteAll(uppers_);
  }
  // Spare node `index` moved to `origin`, or a new node there (holding `background_`, inactive) if
  // there is no such spare. A reused leaf keeps its old values and value mask: the caller sets both
  // (the mapping and the ditherers write every value anyway, and the rasterizer clears only the leaves
  // hasLeaf says are reused, so clearing here would write those leaves twice).
  // Internal nodes are handed out empty (see TreeRecycler::takeSpares). Callers index spares by the
  // output leaf's position in the band, so a band's leaves get spares in address order (see
  // takeSpares); a position the caller skips leaves its spare to be deleted, which is rare (a band
  // leaf with no active voxel in the band's layers) and costs one allocation, not a value.
  std::unique_ptr<LeafT> leaf(std::size_t index, const openvdb::Coord& origin) { return spareOrNew(leaves_, index, origin); }
  std::unique_ptr<ParentT> parent(std::size_t index, const openvdb::Coord& origin) { return spareOrNew(parents_, index, origin); }
  std::unique_ptr<UpperT> upper(std::size_t index, const openvdb::Coord& origin) { return spareOrNew(uppers_, index, origin); }
  // Whether leaf(index, ...) would hand out a reused leaf (whose values the caller must then clear).
  bool hasLeaf(std::size_t index) const { return index < leaves_.size() && leaves_[index]; }

private:
  friend class TreeRecycler<TreeT>;
  template <typename Node>
  std::unique_ptr<Node> spareOrNew(std::vector<Node*>& spares, std::size_t index, const openvdb::Coord& origin) {
    if (index < spares.size() && spares[index]) {
      std::unique_ptr<Node> node(std::exchange(spares[index], nullptr));
      node->setOrigin(origin);
      if constexpr (requires { node->setTransientData(0); }) node->setTransientData(0);  // as a new node's
      return node;
    }
    return std::make_unique<Node>(origin, background_, false);
  }
  template <typename Node>
  static void deleteAll(std::vector<Node*>& nodes) {
    for (Node*& node : nodes) delete std::exchange(node, nullptr);
  }
  typename TreeT::ValueType background_ = openvdb::zeroVal<typename TreeT::ValueType>();
  std::vector<LeafT*> leaves_;
  std::vector<ParentT*> parents_;
  std::vector<UpperT*> uppers_;
};

// The trees a producer made come back here when their last owner lets them go, and the next one is
// built from their nodes. At most keptTrees() trees wait; further ones, and every one let go after the
// recycler is gone, are deleted. Thread-safe: trees come back from any thread, and takeSpares and
// assemble may be called from several threads at once.
// Memory: the kept trees stay allocated while the recycler lives. A slicer's memory estimate counts
// them (voxel::RasterEstimate::peakBytes, diagnostics.hpp: each recycler's keptTrees() band trees).
template <typename TreeT>
class TreeRecycler {
public:
  // Trees kept by default: as many as the slicer's pipeline has bands in flight (slicer::kBandsInFlight),
  // the trees let go while the next bands are made.
  static constexpr std::size_t kKeptTrees = 2;
  using LeafT = typename TreeT::LeafNodeType;
  using ValueT = typename TreeT::ValueType;

  // Trees with background `background`; up to `keptTrees` of them wait to be reused.
  explicit TreeRecycler(ValueT background = openvdb::zeroVal<ValueT>(), std::size_t keptTrees = kKeptTrees)
      : background_(background), returned_(std::make_shared<Returned>()) {
    returned_->kept = keptTrees;
    returned_->trees.reserve(keptTrees);  // so that giving a tree back never allocates
  }
  std::size_t keptTrees() const { return returned_->kept; }

  // The nodes of the tree that came back first (none if no tree came back yet): every leaf, and the
  // internal nodes left empty (an owner may have changed the tree before letting it go; internal nodes
  // that still hold a tile other than the inactive background, bit for bit, are deleted, not reused).
  // The upper nodes and the leaf parents are taken out on the calling thread (a band has a handful of
  // uppers and some hundred parents); each parent's leaves are taken out of it and its table checked
  // in parallel (tbb::parallel_for in the caller's arena), with the uppers' tables in parts of a
  // parent's size: on one thread this check of every reused node's 4096 or 32768 tiles was 4 % of
  // the spring's rasterize + map.
  SpareNodes<TreeT> takeSpares() {
    SpareNodes<TreeT> spares;
    spares.background_ = background_;
    std::unique_ptr<TreeT> tree;
    {
      const std::lock_guard<std::mutex> lock(returned_->mutex);
      if (returned_->trees.empty()) return spares;
      tree = std::move(returned_->trees.front());
      returned_->trees.erase(returned_->trees.begin());
    }
    tree->stealNodes(spares.uppers_, background_, false);  // each replaced by an inactive background tile
    for (UpperT* upper : spares.uppers_) upper->stealNodes(spares.parents_, background_, false);
    takeLeavesAndCheck(spares);
    // In address order: the k-th leaf a producer asks for gets the k-th lowest address, so a band's
    // leaves lie in memory in the order they were made, as fresh allocations from one heap would (in the
    // old tree's order, the layout got more scattered band after band, and every pass over the leaves
    // in order paid for it).
    tbb::parallel_sort(spares.leaves_.begin(), spares.leaves_.end(), std::less<>());
    return spares;
  }

  // assembleTree (see above) into a new tree (background as given to the constructor) with internal
  // nodes from `spares`, that comes back here when its owners let it go.
  template <typename ForEachLeaf>
  typename TreeT::Ptr assemble(std::size_t groupCount, const ForEachLeaf& forEachLeaf, SpareNodes<TreeT>& spares) const {
    auto tree = std::make_unique<TreeT>(background_);
    assembleTree(*tree, groupCount, forEachLeaf, spares);
    return typename TreeT::Ptr(tree.release(), [weak = std::weak_ptr<Returned>(returned_)](TreeT* t) {
      if (const std::shared_ptr<Returned> returned = weak.lock()) {
        const std::lock_guard<std::mutex> lock(returned->mutex);
        if (returned->keeping && returned->trees.size() < returned->kept) {
          returned->trees.emplace_back(t);
          return;
        }
      }
      outsideCancellation([t] { delete t; });  // the last owner may be a task of a cancelled pipeline
    });
  }

  // Deletes the trees waiting to be reused and every tree let go from now on (a producer done
  // streaming gives their memory back before the next, unrelated work); takeSpares then finds none.
  void releaseKept() {
    std::vector<std::unique_ptr<TreeT>> kept;  // deleted after the lock is released
    const std::lock_guard<std::mutex> lock(returned_->mutex);
    kept.swap(returned_->trees);
    returned_->keeping = false;
  }

private:
  struct Returned {
    std::mutex mutex;
    std::vector<std::unique_ptr<TreeT>> trees;
    std::size_t kept = kKeptTrees;  // set once, before any tree comes back
    bool keeping = true;
  };
  using ParentT = LeafParentOf<TreeT>;
  using UpperT = UpperNodeOf<TreeT>;
  // The parents' leaves into spares.leaves_ (in the parents' order), and the parents and uppers that
  // hold anything but the background deleted: parent by parent in parallel, each parent's leaves
  // straight into their place in spares.leaves_ (counted first, so taking them out cannot throw and no
  // leaf is ever owned by anything but a parent or the spares), the uppers' tables in parts of
  // kTilesPerPart tiles alongside.
  void takeLeavesAndCheck(SpareNodes<TreeT>& spares) const {
    static constexpr openvdb::Index kTilesPerPart = ParentT::NUM_VALUES, kPartsPerUpper = UpperT::NUM_VALUES / kTilesPerPart;
    const std::size_t parents = spares.parents_.size();
    std::vector<std::size_t> firstLeafOf(parents + 1, 0);
    for (std::size_t p = 0; p < parents; ++p) firstLeafOf[p + 1] = firstLeafOf[p] + spares.parents_[p]->getChildMask().countOn();
    spares.leaves_.resize(firstLeafOf[parents], nullptr);
    std::vector<unsigned char> partClear(spares.uppers_.size() * kPartsPerUpper, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, parents + partClear.size()), [&](const tbb::blocked_range<std::size_t>& range) {
      for (std::size_t item = range.begin(); item != range.end(); ++item) {
        if (item >= parents) {
          const std::size_t part = item - parents;
          partClear[part] = tilesHoldBackground(*spares.uppers_[part / kPartsPerUpper], openvdb::Index(part % kPartsPerUpper) * kTilesPerPart,
                                                kTilesPerPart);
          continue;
        }
        ParentT*& parent = spares.parents_[item];
        LeafSlots slots{spares.leaves_.data() + firstLeafOf[item]};
        parent->stealNodes(slots, background_, false);
        if (!parent->getValueMask().isOff() || !tilesHoldBackground(*parent, 0, ParentT::NUM_VALUES)) delete std::exchange(parent, nullptr);
      }
    });
    for (std::size_t u = 0; u < spares.uppers_.size(); ++u) {
      UpperT*& upper = spares.uppers_[u];
      const bool clear = upper->getChildMask().isOff() && upper->getValueMask().isOff() &&
                         std::all_of(partClear.begin() + std::ptrdiff_t(u * kPartsPerUpper),
                                     partClear.begin() + std::ptrdiff_t((u + 1) * kPartsPerUpper), [](unsigned char c) { return c != 0; });
      if (!clear) delete std::exchange(upper, nullptr);
    }
  }
  // Where InternalNode::stealNodes puts a parent's leaves: consecutive slots of spares.leaves_, sized
  // beforehand to the parent's child count.
  struct LeafSlots {
    using value_type = LeafT*;
    LeafT** next;
    void push_back(LeafT* leaf) noexcept { *next++ = leaf; }
  };
  // Whether tiles first .. first + count - 1 of the node's table hold the background's bits (the caller
  // checks that none is active or a child). The table's entries are read as words, the value's bytes
  // masked (a union of the value and a child pointer, the value at its start): every word agrees with
  // the background on those bytes exactly where the OR and the AND of all the words do, a loop
  // without branches that the compiler vectorizes (Node::isConstant's loop cost 3 % of the streamed
  // spring's rasterize + map). A tile that equals the background but for its bits (-0 for 0) gets the
  // node deleted, never wrongly reused.
  template <typename Node>
  bool tilesHoldBackground(const Node& node, openvdb::Index first, openvdb::Index count) const {
    const auto* table = node.getTable() + first;
    static_assert(sizeof(*table) == sizeof(std::uint64_t) && sizeof(ValueT) <= sizeof(std::uint64_t),
                  "a tile is a value or a child pointer in one word");
    std::uint64_t backgroundBits = 0, valueBits = 0;
    std::memcpy(&backgroundBits, &background_, sizeof(ValueT));
    std::memset(&valueBits, 0xff, sizeof(ValueT));
    // Eight words a step, two to a vector (GNU vector extension: SSE2 registers in the baseline build),
    // four accumulators of each kind: 1.9 instead of 3 instructions a word. count is a multiple of
    // eight (a node's table, or parts of it).
    typedef std::uint64_t Words2 __attribute__((vector_size(16)));
    constexpr openvdb::Index kStep = 8, kVectors = kStep / 2;
    static_assert(Node::NUM_VALUES % kStep == 0, "whole steps");
    Words2 anyOn[kVectors] = {}, allOn[kVectors];
    for (Words2& a : allOn) a = ~Words2{};
    for (openvdb::Index n = 0; n < count; n += kStep)
      for (openvdb::Index v = 0; v < kVectors; ++v) {
        Words2 words;
        std::memcpy(&words, &table[n + 2 * v], sizeof words);
        anyOn[v] |= words;
        allOn[v] &= words;
      }
    std::uint64_t differ = 0;
    for (openvdb::Index v = 0; v < kVectors; ++v)
      for (int l = 0; l < 2; ++l) differ |= (anyOn[v][l] ^ backgroundBits) | (allOn[v][l] ^ backgroundBits);
    return (differ & valueBits) == 0;
  }
  ValueT background_;
  std::shared_ptr<Returned> returned_;
};

}  // namespace rodfab::voxel
