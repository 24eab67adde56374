// Internal: reading OpenVDB leaf masks a byte at a time. A leaf holds 8 x 8 x 8 voxels at linear
// offset (x << 6) | (y << 3) | z, so byte x * 8 + y of its mask holds the 8 voxels of column (x, y)
// along z, bit z. Image rows need the 8 voxels along x of one (y, z) instead, gathered below.
#pragma once

#include <openvdb/openvdb.h>

#include <array>
#include <bit>
#include <cstdint>
#include <cstring>

namespace rodfab::printer_profiles {

static_assert(std::endian::native == std::endian::little, "leaf mask bytes are read as little-endian words");
static_assert(openvdb::BoolTree::LeafNodeType::DIM == 8 && openvdb::FloatTree::LeafNodeType::DIM == 8,
              "the bitmap packing assumes 8-voxel leaves");

// The 64 bytes of one leaf's 512 bits (a mask or a bool leaf's values).
struct LeafBytes {
  std::array<std::uint8_t, 64> bytes{};

  // The 8 voxels along z of column (x, y), bit z.
  std::uint8_t column(int x, int y) const { return bytes[static_cast<std::size_t>(x * 8 + y)]; }
  // The 8 voxels along x of row y, layer z, packed as image bits (x = 0 in bit 7).
  std::uint8_t row(int y, int z) const {
    std::uint8_t out = 0;
    for (int x = 0; x < 8; ++x) out = static_cast<std::uint8_t>(out | (((column(x, y) >> z) & 1u) << (7 - x)));
    return out;
  }
};

// A leaf's bits as image rows: byte z * 8 + y holds LeafBytes::row(y, z). Gathered once per leaf, so a
// layer reads its 8 rows of the leaf as bytes instead of gathering each bit by bit, layer after layer.
struct LeafRows {
  std::array<std::uint8_t, 64> bytes{};

  LeafRows() = default;  // no voxel
  // Per y, the 8 x 8 bit matrix of columns x (bits z) transposed into rows z (bits x, x = 0 in bit 7):
  // with column x in byte 7 - x of a word, bit 8 (7 - x) + z, the transpose (three delta swaps,
  // Hacker's Delight 7-3) puts it at bit 8 z + 7 - x, which is byte z in image bit order.
  explicit LeafRows(const LeafBytes& leaf) {
    for (int y = 0; y < 8; ++y) {
      std::uint64_t m = 0;
      for (int x = 0; x < 8; ++x) m |= std::uint64_t{leaf.column(x, y)} << (8 * (7 - x));
      std::uint64_t t = (m ^ (m >> 7)) & 0x00AA00AA00AA00AAull;
      m ^= t ^ (t << 7);
      t = (m ^ (m >> 14)) & 0x0000CCCC0000CCCCull;
      m ^= t ^ (t << 14);
      t = (m ^ (m >> 28)) & 0x00000000F0F0F0F0ull;
      m ^= t ^ (t << 28);
      for (int z = 0; z < 8; ++z) bytes[static_cast<std::size_t>(z * 8 + y)] = static_cast<std::uint8_t>(m >> (8 * z));
    }
  }
  std::uint8_t row(int y, int z) const { return bytes[static_cast<std::size_t>(z * 8 + y)]; }
  // Layer z's 8 rows at once: row y in byte y (bits y * 8 .. y * 8 + 7), as a little-endian load gives them.
  std::uint64_t layer(int z) const {
    static_assert(std::endian::native == std::endian::little, "layer() reads the 8 row bytes as one little-endian word");
    std::uint64_t rows = 0;
    std::memcpy(&rows, bytes.data() + z * 8, 8);
    return rows;
  }
};

template <typename MaskT>
LeafBytes maskBytes(const MaskT& mask) {
  LeafBytes out;
  for (openvdb::Index n = 0; n < 8; ++n) {
    const auto word = mask.template getWord<openvdb::Index64>(n);
    std::memcpy(out.bytes.data() + 8 * n, &word, 8);
  }
  return out;
}

inline LeafBytes boolValueBytes(const openvdb::BoolTree::LeafNodeType& leaf) {
  LeafBytes out;
  std::memcpy(out.bytes.data(), leaf.buffer().data(), 64);
  return out;
}

// Calls fn(box, value) for every active tile above the leaf level (a region pruned to one value).
template <typename TreeT, typename Fn>
void forEachActiveTile(const TreeT& tree, Fn&& fn) {
  typename TreeT::ValueOnCIter it = tree.cbeginValueOn();
  it.setMaxDepth(TreeT::ValueOnCIter::LEAF_DEPTH - 1);
  for (; it; ++it) {
    if (it.isVoxelValue()) continue;
    openvdb::CoordBBox box;
    it.getBoundingBox(box);
    fn(box, *it);
  }
}

}  // namespace rodfab::printer_profiles
