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
// Threads: runs in the caller's TBB arena (tbb::parallel_for over the groups). The tree's shape and
// contents do not depend on the thread count, and neither do the indices passed to `nodes`.
#pragma once

#include <openvdb/openvdb.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstddef>
#include <memory>
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
        parents[g]->addChild(leaf.release());
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
    (*upper)->addChild(parent.release());
  }
}

}  // namespace rodfab::voxel
