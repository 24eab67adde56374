#include "common/xxh128.hpp"
#include "common/xxhash_dispatch.hpp"

namespace rodfab::common {

namespace {

std::string canonicalHex(XXH128_hash_t hash) {
  static constexpr char kHex[] = "0123456789abcdef";
  XXH128_canonical_t canonical;
  XXH128_canonicalFromHash(&canonical, hash);
  std::string hex;
  hex.reserve(2 * sizeof canonical.digest);
  for (const unsigned char byte : canonical.digest) {
    hex += kHex[byte >> 4];
    hex += kHex[byte & 15];
  }
  return hex;
}

}  // namespace

std::string xxh128Hex(std::span<const std::uint8_t> data) { return canonicalHex(XXH3_128bits(data.data(), data.size())); }

std::string xxh128Hex(std::string_view data) { return canonicalHex(XXH3_128bits(data.data(), data.size())); }

bool isXxh128Hex(std::string_view text) {
  return text.size() == 32 && text.find_first_not_of("0123456789abcdef") == std::string_view::npos;
}

}  // namespace rodfab::common
