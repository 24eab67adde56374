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
  // Word x of the leaf's bytes holds column (x, y) in byte y, bit z: in each byte lane y an 8 x 8 bit
  // matrix, row x, bit z. Transposed in all 8 lanes at once (the three block swaps of Hacker's Delight
  // 7-3, their masks repeated in every byte, so nothing crosses a lane), it becomes word z, row y in
  // byte y, bit x; taking the words in reverse x puts x at bit 7 - x, the image's order. A few dozen
  // word operations a leaf instead of gathering the 8 bytes of each lane and transposing lane by lane.
  explicit LeafRows(const LeafBytes& leaf) {
    std::array<std::uint64_t, 8> w{};
    for (std::size_t i = 0; i < 8; ++i) std::memcpy(&w[i], leaf.bytes.data() + 8 * (7 - i), 8);
    constexpr std::array<std::uint64_t, 3> kLowHalves = {0x0f0f0f0f0f0f0f0full, 0x3333333333333333ull, 0x5555555555555555ull};
    for (std::size_t stage = 0, s = 4; stage < 3; ++stage, s /= 2)
      for (std::size_t i = 0; i < 8; ++i)
        if (!(i & s)) {  // swaps the high s bits of word i's lanes with the low s bits of word i + s's
          const std::uint64_t t = ((w[i] >> s) ^ w[i + s]) & kLowHalves[stage];
          w[i + s] ^= t;
          w[i] ^= t << s;
        }
    std::memcpy(bytes.data(), w.data(), 64);
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
