#include "materials/band_leaves.hpp"

#include "materials/ditherer.hpp"
#include "voxel/tree_assembly.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

namespace rodfab::materials::detail {

LeafGroups leafGroupsInLayers(const openvdb::FloatTree& tree, int k0, int k1) {
  // Visit the leaf parents (128^3 voxels each) and skip the ones outside the band: a slicer streaming a
  // tall job calls this once per band, and the parents are a few hundred times fewer than the leaves.
  using LeafParent = openvdb::FloatTree::RootNodeType::ChildNodeType::ChildNodeType;
  std::vector<const LeafParent*> parents;
  tree.getNodes(parents);
  LeafGroups groups;
  for (const LeafParent* parent : parents) {
    const int z = parent->origin().z();
    if (z >= k1 || z + static_cast<int>(LeafParent::DIM) <= k0) continue;
    for (auto it = parent->cbeginChildOn(); it; ++it) {
      const int leafZ = it->origin().z();
      if (leafZ < k1 && leafZ + static_cast<int>(FloatLeaf::DIM) > k0) groups.leaves.push_back(&*it);
    }
    if (groups.leaves.size() > groups.begin.back()) groups.begin.push_back(groups.leaves.size());
  }
  return groups;
}

std::vector<const FloatLeaf*> leavesInLayers(const openvdb::FloatTree& tree, int k0, int k1, LeafOrder order) {
  std::vector<const FloatLeaf*> leaves = std::move(leafGroupsInLayers(tree, k0, k1).leaves);
  if (order == LeafOrder::Tree) return leaves;
  std::sort(leaves.begin(), leaves.end(), [](const FloatLeaf* a, const FloatLeaf* b) {
    const openvdb::Coord& p = a->origin();
    const openvdb::Coord& q = b->origin();
    return std::tuple(p.z(), p.y(), p.x()) < std::tuple(q.z(), q.y(), q.x());
  });
  return leaves;
}

LeafMask activeInLayers(const FloatLeaf& leaf, int k0, int k1) {
  const int z0 = leaf.origin().z();
  const int lo = std::clamp(k0 - z0, 0, 8), hi = std::clamp(k1 - z0, 0, 8);
  LeafMask mask = leaf.getValueMask();
  if (lo == 0 && hi == 8) return mask;
  // Offsets are x * 64 + y * 8 + z: every byte of a 64-bit mask word is one (x, y) column along z.
  const std::uint64_t column = hi > lo ? ((std::uint64_t{1} << hi) - (std::uint64_t{1} << lo)) : 0;
  const std::uint64_t keep = column * 0x0101010101010101ull;
  for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) mask.template getWord<std::uint64_t>(w) &= keep;
  return mask;
}

void FractionCheck::throwIfFailed(const openvdb::FloatGrid& grid, const std::vector<const FloatLeaf*>& leaves) const {
  const std::uint64_t position = first_.load();
  if (position == ~std::uint64_t{0}) return;
  const FloatLeaf& leaf = *leaves[position / FloatLeaf::SIZE];
  const auto offset = static_cast<openvdb::Index>(position % FloatLeaf::SIZE);
  const openvdb::Coord ijk = leaf.offsetToGlobalCoord(offset);
  const std::string name = grid.getName().empty() ? std::string(kFractionGridName) : grid.getName();
  throw std::invalid_argument("grid '" + name + "': voxel (" + std::to_string(ijk.x()) + ", " +
                              std::to_string(ijk.y()) + ", " + std::to_string(ijk.z()) + ") has fraction " +
                              std::to_string(leaf.getValue(offset)) + ", expected a Vero fraction in [0, 1]");
}

void throwFirstInvalid(const openvdb::FloatGrid& fraction, int k0, int k1) {
  const std::vector<const FloatLeaf*> leaves = leavesInLayers(fraction.tree(), k0, k1, LeafOrder::ZYX);
  FractionCheck check;
  for (std::size_t l = 0; l < leaves.size() && !check.failed(); ++l) {
    const LeafMask mask = activeInLayers(*leaves[l], k0, k1);
    for (auto it = mask.beginOn(); it; ++it)
      if (!FractionCheck::valid(leaves[l]->getValue(it.pos()))) {
        check.fail(l, it.pos());
        break;
      }
  }
  check.throwIfFailed(fraction, leaves);
}

openvdb::BoolTree::Ptr OutputTreeRecycler::assemble(const LeafGroups& groups, std::vector<std::unique_ptr<BoolLeaf>>& leaves,
                                                    SpareNodes& spares) const {
  const auto forEachLeaf = [&](std::size_t p, const auto& visit) {
    for (std::size_t l = groups.begin[p]; l != groups.begin[p + 1]; ++l) visit(leaves[l]);
  };
  return voxel::TreeRecycler<openvdb::BoolTree>::assemble(groups.parentCount(), forEachLeaf, spares);
}

openvdb::BoolGrid::Ptr materialGrid(openvdb::BoolTree::Ptr tree, const openvdb::FloatGrid& like) {
  auto grid = openvdb::BoolGrid::create(tree);
  grid->setTransform(like.transform().copy());
  grid->setName(kMaterialGridName);
  return grid;
}

}  // namespace rodfab::materials::detail
