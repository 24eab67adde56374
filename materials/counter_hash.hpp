// Counter-based random numbers (Random123's Philox4x32-10): a pure function of (seed, counter), so a
// voxel's number never depends on which thread asks or in which order. Internal to materials/.
#pragma once

#include <Random123/philox.h>
#include <Random123/u01fixedpt.h>

#include <cstdint>

namespace rodfab::materials {

// Streams keep the different uses of one seed independent.
enum class HashStream : std::uint32_t { VoxelUniform = 0, MaskOffset = 1, MaskGenerator = 2, WhiteNoiseLeaf = 3 };

inline r123::Philox4x32::ctr_type philox(std::uint64_t seed, std::uint32_t a, std::uint32_t b, std::uint32_t c,
                                         HashStream stream) {
  const r123::Philox4x32::ctr_type counter = {{a, b, c, static_cast<std::uint32_t>(stream)}};
  const r123::Philox4x32::key_type key = {{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32)}};
  return r123::Philox4x32()(counter, key);
}

// Uniform in [0, 1) on the 2^24 grid a float holds exactly, for voxel (i, j, k) (error diffusion's
// threshold jitter).
inline float voxelUniform(std::uint64_t seed, int i, int j, int k) {
  return u01fixedpt_closed_open_32_float(philox(seed, static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j),
                                                static_cast<std::uint32_t>(k), HashStream::VoxelUniform)[0]);
}

// Uniform in [0, 1) (53 bits) for an index, used by the mask generator's random start.
inline double unitHash(std::uint64_t seed, std::uint64_t index) {
  const auto r = philox(seed, static_cast<std::uint32_t>(index), static_cast<std::uint32_t>(index >> 32), 0,
                        HashStream::MaskGenerator);
  return u01fixedpt_closed_open_64_double((static_cast<std::uint64_t>(r[0]) << 32) | r[1]);
}

// White noise, in two levels because a Philox draw per voxel cost more than the rest of dithering:
// a 64-bit key per 8 x 8 x 8 leaf from Philox on (seed, leaf origin), then SplitMix64 (Steele, Lea and
// Flood 2014: a Weyl sequence through a 64-bit finalizer) started at that key for the leaf's 512 voxels
// in offset order. Still a pure function of (seed, i, j, k), since leaves sit on a fixed 8^3 lattice.
inline std::uint64_t whiteNoiseLeafKey(std::uint64_t seed, int x, int y, int z) {
  const auto r = philox(seed, static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y), static_cast<std::uint32_t>(z),
                        HashStream::WhiteNoiseLeaf);
  return (static_cast<std::uint64_t>(r[0]) << 32) | r[1];
}

// The SplitMix64 output for the voxel at `offset` (0 .. 511) of the leaf keyed `leafKey`.
inline std::uint64_t whiteNoiseBits(std::uint64_t leafKey, std::uint32_t offset) {
  std::uint64_t z = leafKey + (offset + std::uint64_t{1}) * 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// Its top 24 bits as a uniform number in [0, 1), on the grid a float holds exactly.
inline float whiteNoiseUniform(std::uint64_t leafKey, std::uint32_t offset) {
  return static_cast<float>(static_cast<std::uint32_t>(whiteNoiseBits(leafKey, offset) >> 40)) * 0x1p-24f;
}

}  // namespace rodfab::materials
