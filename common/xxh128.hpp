// XXH3-128 checksums (libxxhash), the digest of a print job's files in its manifest: every layer image
// is hashed as it is written, and SHA-256 at about 1.6 GB/s a core was a fifth of a whole slice's CPU
// (printer_profiles/README.md, "Checksums"). XXH3 is not cryptographic: it guards a job against damage
// (a truncated copy, a flipped bit, a file swapped for another), not against someone forging one. The
// design and calibration a job names keep SHA-256 (common/sha256.hpp).
//
// Digests are returned as 32 lowercase hex digits in XXH128's canonical (big-endian) order, which is
// what `xxhsum -H2` prints. The functions are reentrant. Streamed data: common::FileHasher
// (common/file_hasher.hpp).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace rodfab::common {

// Lowercase hex XXH3-128 of `data`.
std::string xxh128Hex(std::span<const std::uint8_t> data);
std::string xxh128Hex(std::string_view data);

// True when `text` is 32 lowercase hex digits (how the functions above write a digest).
bool isXxh128Hex(std::string_view text);

}  // namespace rodfab::common
