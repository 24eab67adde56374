// voxel/tree_assembly.hpp: trees assembled parent by parent against OpenVDB's own Tree::addLeaf, the
// rules it enforces (errors instead of voxels silently lost) and the recycler's reuse of nodes.
#include "voxel/tree_assembly.hpp"

#include <catch2/catch.hpp>

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <malloc.h>

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <vector>

namespace {

using rodfab::voxel::assembleTree;
using rodfab::voxel::FreshNodes;
using rodfab::voxel::LeafParentOf;
using rodfab::voxel::TreeRecycler;
using FloatLeaf = openvdb::FloatTree::LeafNodeType;
using Groups = std::vector<std::vector<std::unique_ptr<FloatLeaf>>>;

// Leaves at random places (some far apart, some negative), each with a few values set from its origin;
// grouped by their leaf parent, in a fixed order.
Groups randomLeafGroups(unsigned seed, int count) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> coordinate(-700, 700);
  std::map<openvdb::Coord, std::vector<std::unique_ptr<FloatLeaf>>> byParent;
  std::set<openvdb::Coord> used;
  const int parentDim = LeafParentOf<openvdb::FloatTree>::DIM;
  while (int(used.size()) < count) {
    const openvdb::Coord origin = openvdb::Coord(coordinate(rng), coordinate(rng), coordinate(rng)) & ~(FloatLeaf::DIM - 1);
    if (!used.insert(origin).second) continue;
    auto leaf = std::make_unique<FloatLeaf>(origin, 0.0f, false);
    for (int i = 0; i < 5; ++i) leaf->setValueOn(openvdb::Index(rng() % FloatLeaf::SIZE), float(origin.x() + 3 * origin.y() + 7 * origin.z() + i));
    byParent[origin & ~(parentDim - 1)].push_back(std::move(leaf));
  }
  Groups groups;
  for (auto& [parent, leaves] : byParent) groups.push_back(std::move(leaves));
  return groups;
}

Groups copyOf(const Groups& groups) {
  Groups copy(groups.size());
  for (std::size_t g = 0; g < groups.size(); ++g)
    for (const auto& leaf : groups[g]) copy[g].push_back(std::make_unique<FloatLeaf>(*leaf));
  return copy;
}

auto visitorOf(Groups& groups) {
  return [&groups](std::size_t g, const auto& visit) {
    for (auto& leaf : groups[g]) visit(leaf);
  };
}

// The truth: the same leaves added one by one by OpenVDB.
openvdb::FloatTree addedOneByOne(const Groups& groups) {
  openvdb::FloatTree tree(0.0f);
  for (const auto& group : groups)
    for (const auto& leaf : group) tree.addLeaf(new FloatLeaf(*leaf));
  return tree;
}

void requireSameTree(const openvdb::FloatTree& a, const openvdb::FloatTree& b) {
  REQUIRE(a.leafCount() == b.leafCount());
  REQUIRE(a.activeVoxelCount() == b.activeVoxelCount());
  REQUIRE(a.nonLeafCount() == b.nonLeafCount());
  for (auto leaf = a.cbeginLeaf(); leaf; ++leaf) {
    const FloatLeaf* other = b.probeConstLeaf(leaf->origin());
    REQUIRE(other != nullptr);
    REQUIRE(other->getValueMask() == leaf->getValueMask());
    for (auto v = leaf->cbeginValueOn(); v; ++v) REQUIRE(other->getValue(v.pos()) == *v);
  }
}

}  // namespace

TEST_CASE("assembleTree builds the tree Tree::addLeaf builds, whatever the thread count", "[voxel][tree_assembly]") {
  for (const int threads : {1, 2}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    Groups groups = randomLeafGroups(17u + unsigned(threads), 600);
    const openvdb::FloatTree truth = addedOneByOne(groups);
    openvdb::FloatTree tree(0.0f);
    FreshNodes<openvdb::FloatTree> fresh{0.0f};
    assembleTree(tree, groups.size(), visitorOf(groups), fresh);
    requireSameTree(tree, truth);
    requireSameTree(truth, tree);
    for (const auto& group : groups)
      for (const auto& leaf : group) CHECK(leaf == nullptr);  // all handed over
  }
}

TEST_CASE("assembleTree refuses what would lose voxels silently", "[voxel][tree_assembly][errors]") {
  FreshNodes<openvdb::FloatTree> fresh{0.0f};
  const int parentDim = LeafParentOf<openvdb::FloatTree>::DIM;
  const auto leafAt = [](int x, int y, int z) { return std::make_unique<FloatLeaf>(openvdb::Coord(x, y, z), 0.0f, true); };
  SECTION("two leaves of a group at one origin") {
    Groups groups(1);
    groups[0].push_back(leafAt(8, 0, 0));
    groups[0].push_back(leafAt(8, 0, 0));
    openvdb::FloatTree tree(0.0f);
    CHECK_THROWS_WITH(assembleTree(tree, groups.size(), visitorOf(groups), fresh), Catch::Contains("handed over twice"));
    CHECK(groups[0][1] != nullptr);  // the refused leaf stays with its slot
  }
  SECTION("a leaf outside its group's parent") {
    Groups groups(1);
    groups[0].push_back(leafAt(0, 0, 0));
    groups[0].push_back(leafAt(parentDim, 0, 0));
    openvdb::FloatTree tree(0.0f);
    CHECK_THROWS_WITH(assembleTree(tree, groups.size(), visitorOf(groups), fresh), Catch::Contains("outside its parent"));
  }
  SECTION("two groups sharing a parent") {
    Groups groups(2);
    groups[0].push_back(leafAt(0, 0, 0));
    groups[1].push_back(leafAt(8, 0, 0));
    openvdb::FloatTree tree(0.0f);
    CHECK_THROWS_WITH(assembleTree(tree, groups.size(), visitorOf(groups), fresh), Catch::Contains("handed over twice"));
    CHECK(tree.leafCount() == 1);  // the first group's leaf is in the tree, the second group's parent was not added
  }
}

TEST_CASE("TreeRecycler builds the next tree from the nodes of the ones let go, and the trees stay exact", "[voxel][tree_assembly]") {
  TreeRecycler<openvdb::FloatTree> recycler(0.0f);
  std::set<const FloatLeaf*> earlier;
  std::size_t reused = 0, leaves = 0;
  for (unsigned band = 0; band < 4; ++band) {
    const Groups source = randomLeafGroups(100u + band, 300);
    auto spares = recycler.takeSpares();
    // Leaves made the way the producers make them: spare k for the k-th leaf, values set in full.
    Groups groups(source.size());
    std::size_t k = 0;
    for (std::size_t g = 0; g < source.size(); ++g)
      for (const auto& leaf : source[g]) {
        const bool spare = spares.hasLeaf(k);
        auto made = spares.leaf(k++, leaf->origin());
        made->setValuesOff();
        made->fill(0.0f, false);
        for (auto v = leaf->cbeginValueOn(); v; ++v) made->setValueOn(v.pos(), *v);
        reused += spare && earlier.count(made.get());  // the recycler's word and the address agree
        groups[g].push_back(std::move(made));
      }
    leaves += k;
    openvdb::FloatTree::Ptr tree = recycler.assemble(groups.size(), visitorOf(groups), spares);
    requireSameTree(*tree, addedOneByOne(copyOf(source)));
    for (auto leaf = tree->cbeginLeaf(); leaf; ++leaf) earlier.insert(leaf.getLeaf());
    tree.reset();  // let go: back to the recycler
  }
  // Bands 1-3 each find band n-1's 300 leaves waiting.
  CAPTURE(reused, leaves);
  CHECK(reused >= 3 * 300);
}

TEST_CASE("TreeRecycler::releaseKept frees the waiting trees and keeps none let go later", "[voxel][tree_assembly]") {
  TreeRecycler<openvdb::FloatTree> recycler(0.0f);
  const auto make = [&] {
    Groups groups = randomLeafGroups(7u, 50);
    auto spares = recycler.takeSpares();
    return recycler.assemble(groups.size(), visitorOf(groups), spares);
  };
  openvdb::FloatTree::Ptr first = make(), second = make();
  first.reset();
  REQUIRE(recycler.takeSpares().hasLeaf(0));  // a let-go tree waits (and is taken: the queue is empty again)
  second.reset();
  recycler.releaseKept();
  CHECK_FALSE(recycler.takeSpares().hasLeaf(0));
  openvdb::FloatTree::Ptr third = make();
  CHECK(third->leafCount() == 50);  // still assembles, from fresh nodes
  third.reset();
  CHECK_FALSE(recycler.takeSpares().hasLeaf(0));
}

TEST_CASE("TreeRecycler reuses no internal node an owner left holding a tile other than the background", "[voxel][tree_assembly]") {
  for (const float background : {0.0f, 2.0f})
  for (const int threads : {1, 2}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    TreeRecycler<openvdb::FloatTree> recycler(background, 1);
    const Groups source = randomLeafGroups(31u, 200);
    const auto make = [&] {
      auto spares = recycler.takeSpares();
      Groups groups = copyOf(source);
      return recycler.assemble(groups.size(), visitorOf(groups), spares);
    };
    // A leaf's place in group g's parent that holds no leaf of the source.
    const int parentDim = LeafParentOf<openvdb::FloatTree>::DIM;
    const auto freeLeafIn = [&](std::size_t g) {
      const openvdb::Coord parent = source[g][0]->origin() & ~(parentDim - 1);
      for (int x = 0;; x += FloatLeaf::DIM) {
        const openvdb::Coord at = parent.offsetBy(x, 0, 0);
        if (std::none_of(source[g].begin(), source[g].end(), [&](const auto& leaf) { return leaf->origin() == at; })) return at;
      }
    };
    // Owners' changes the recycler must notice, in nodes it would otherwise reuse (the next tree has
    // the same leaves, so it asks for every parent and upper again): an inactive tile of another value
    // in a leaf parent, the background with its sign bit flipped in another (-0 for 0: equal as a
    // float, not as bits), with its lowest bit flipped in a third and its bit 30 in a fourth (a bit
    // the background 2 has: the tile 0), an active background tile in a fifth, and an inactive tile in
    // an upper node (a parent's worth of voxels far from the leaves, which lie within 700 of the origin).
    const auto flipped = [&](std::uint32_t bits) { return std::bit_cast<float>(std::bit_cast<std::uint32_t>(background) ^ bits); };
    openvdb::FloatTree::Ptr first = make();
    first->fill(openvdb::CoordBBox::createCube(freeLeafIn(0), FloatLeaf::DIM), 7.0f, false);
    first->fill(openvdb::CoordBBox::createCube(freeLeafIn(1), FloatLeaf::DIM), flipped(0x80000000u), false);
    first->fill(openvdb::CoordBBox::createCube(freeLeafIn(2), FloatLeaf::DIM), flipped(1u), false);
    first->fill(openvdb::CoordBBox::createCube(freeLeafIn(3), FloatLeaf::DIM), flipped(0x40000000u), false);
    first->fill(openvdb::CoordBBox::createCube(freeLeafIn(4), FloatLeaf::DIM), background, true);
    const openvdb::Coord inUpper(30 * parentDim, 30 * parentDim, 30 * parentDim);
    first->fill(openvdb::CoordBBox::createCube(inUpper, parentDim), 3.0f, false);
    REQUIRE(first->getValue(freeLeafIn(0)) == 7.0f);
    REQUIRE(first->getValue(inUpper) == 3.0f);
    REQUIRE(first->leafCount() == 200);  // the tiles went into the nodes that were there
    const openvdb::Index64 nonLeaves = first->nonLeafCount();
    first.reset();  // let go with those tiles
    openvdb::FloatTree::Ptr second = make();
    requireSameTree(*second, addedOneByOne(source));
    REQUIRE(second->nonLeafCount() == nonLeaves);
    // Every tile of the new tree is the background's bits, inactive: no node kept an owner's tile.
    for (auto tile = second->cbeginValueAll(); tile; ++tile) {
      if (tile.isVoxelValue()) continue;
      CAPTURE(tile.getCoord(), tile.getLevel(), background, threads);
      CHECK_FALSE(tile.isValueOn());
      CHECK(std::bit_cast<std::uint32_t>(*tile) == std::bit_cast<std::uint32_t>(background));
    }
  }
}

// Bytes the allocator has handed out and not had back: glibc's every arena and its mmapped blocks.
// AddressSanitizer's allocator does not report through mallinfo2; there its leak check finds a leak.
#if !defined(__SANITIZE_ADDRESS__)
static std::size_t heapBytesInUse() {
  const struct mallinfo2 info = ::mallinfo2();
  return info.uordblks + info.hblkhd;
}

// Lets go of `tree` in a body of a parallel loop whose context is being cancelled (as a pipeline stage is
// after another stage threw), through outsideCancellation or not; the heap bytes it leaves in use.
template <typename Ptr>
static std::ptrdiff_t heapLeftAfterLettingGoWhileCancelled(Ptr& tree, bool outside) {
  tbb::task_group_context cancelling;
  const std::size_t before = heapBytesInUse();
  tbb::parallel_for(0, 1, [&](int) {
    cancelling.cancel_group_execution();
    if (outside) rodfab::voxel::outsideCancellation([&] { tree.reset(); });
    else tree.reset();
  }, cancelling);
  REQUIRE(cancelling.is_group_execution_cancelled());
  return std::ptrdiff_t(heapBytesInUse()) - std::ptrdiff_t(before);
}

TEST_CASE("outsideCancellation: a tree let go in a cancelled TBB context frees its nodes, as OpenVDB alone does not", "[voxel][tree_assembly]") {
  constexpr std::ptrdiff_t kTreeBytes = 128 * 128 * 128 * sizeof(float);  // 8 MiB of leaf values
  const auto denseTree = [] {
    auto tree = std::make_unique<openvdb::FloatTree>(0.0f);
    tree->denseFill(openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(127)), 1.0f, true);
    return tree;
  };
  {
    auto tree = denseTree();
    const std::size_t held = heapBytesInUse();
    tree.reset();
    REQUIRE(held - heapBytesInUse() >= std::size_t(kTreeBytes));  // what the allocator figures can see
  }
  auto tree = denseTree();
  CHECK(heapLeftAfterLettingGoWhileCancelled(tree, true) < -kTreeBytes);
  // The hazard itself: OpenVDB's ~Tree frees the nodes in a tbb::parallel_for, which a cancelled
  // context skips (the nodes leak: deliberately, once, in this process).
  tree = denseTree();
  CHECK(heapLeftAfterLettingGoWhileCancelled(tree, false) > -kTreeBytes / 8);
  // A recycler that keeps no tree deletes the ones let go, wherever that happens.
  TreeRecycler<openvdb::FloatTree> recycler(0.0f, 0);
  Groups groups = randomLeafGroups(11u, 4000);  // 4000 leaves of 2 kB values each
  auto spares = recycler.takeSpares();
  openvdb::FloatTree::Ptr recycled = recycler.assemble(groups.size(), visitorOf(groups), spares);
  REQUIRE(recycled->leafCount() == 4000);
  CHECK(heapLeftAfterLettingGoWhileCancelled(recycled, true) < -4000 * std::ptrdiff_t(sizeof(float) * FloatLeaf::SIZE));
}
#endif
