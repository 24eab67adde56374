// XXH3-128 checksums (libxxhash), the digest of a print job's files in its manifest: every layer image
// is hashed as it is written, and SHA-256 at about 1.6 GB/s a core was a fifth of a whole slice's CPU
// (printer_profiles/README.md, "Checksums"). XXH3 is not cryptographic: it guards a job against damage
// (a truncated copy, a flipped bit, a file swapped for another), not against someone forging one. The
// design and calibration a job names keep SHA-256 (common/sha256.hpp).
//
// Digests are returned as 32 lowercase hex digits in XXH128's canonical (big-endian) order, which is
// what `xxhsum -H2` prints. Thread safety: the free functions are reentrant; one Xxh128 object must not
// be used from two threads at once (separate objects may). Errors (allocation failure): std::bad_alloc.
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

// Incremental XXH3-128, for data that streams (a file checked as it is read).
class Xxh128 {
public:
  Xxh128();
  ~Xxh128();
  Xxh128(const Xxh128&) = delete;
  Xxh128& operator=(const Xxh128&) = delete;
  void update(std::span<const std::uint8_t> data);
  // The digest of everything given to update() so far.
  std::string hex() const;

private:
  void* state_;  // XXH3_state_t, kept out of this header
};

}  // namespace rodfab::common
