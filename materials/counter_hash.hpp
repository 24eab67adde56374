// Counter-based random numbers (Random123's Philox4x32-10): a pure function of (seed, counter), so a
// voxel's number never depends on which thread asks or in which order. Internal to materials/.
#pragma once

#include <Random123/philox.h>
#include <Random123/u01fixedpt.h>

#include <cstdint>

namespace rodfab::materials {

// Streams keep the different uses of one seed independent.
enum class HashStream : std::uint32_t { WhiteNoise = 0, MaskOffset = 1, MaskGenerator = 2 };

inline r123::Philox4x32::ctr_type philox(std::uint64_t seed, std::uint32_t a, std::uint32_t b, std::uint32_t c,
                                         HashStream stream) {
  const r123::Philox4x32::ctr_type counter = {{a, b, c, static_cast<std::uint32_t>(stream)}};
  const r123::Philox4x32::key_type key = {{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32)}};
  return r123::Philox4x32()(counter, key);
}

// Uniform in [0, 1) on the 2^24 grid a float holds exactly, for voxel (i, j, k).
inline float voxelUniform(std::uint64_t seed, int i, int j, int k) {
  return u01fixedpt_closed_open_32_float(philox(seed, static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j),
                                                static_cast<std::uint32_t>(k), HashStream::WhiteNoise)[0]);
}

// Uniform in [0, 1) (53 bits) for an index, used by the mask generator's random start.
inline double unitHash(std::uint64_t seed, std::uint64_t index) {
  const auto r = philox(seed, static_cast<std::uint32_t>(index), static_cast<std::uint32_t>(index >> 32), 0,
                        HashStream::MaskGenerator);
  return u01fixedpt_closed_open_64_double((static_cast<std::uint64_t>(r[0]) << 32) | r[1]);
}

}  // namespace rodfab::materials
