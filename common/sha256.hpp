// SHA-256 checksums (OpenSSL EVP), the one implementation every stage uses: job files and their
// manifest, calibration data and calibration files, the design and calibration a job names.
//
// Digests are returned as 64 lowercase hex digits. Errors (OpenSSL unable to provide SHA-256) are
// std::runtime_error. Thread safety: the free functions are reentrant; one Sha256 object must not be
// used from two threads at once (separate objects may).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace rodfab::common {

// Lowercase hex SHA-256 of `data`.
std::string sha256Hex(std::span<const std::uint8_t> data);
std::string sha256Hex(std::string_view data);

// True when `text` is 64 lowercase hex digits (how the functions above write a digest).
bool isSha256Hex(std::string_view text);

// Incremental SHA-256, for data that streams (a file checked as it is read).
class Sha256 {
public:
  Sha256();  // throws std::runtime_error when OpenSSL cannot provide SHA-256
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void update(std::span<const std::uint8_t> data);
  // The digest of everything given to update(); call once (the object is finished afterwards).
  std::string hex();

private:
  void* context_;  // EVP_MD_CTX, kept out of this header
};

}  // namespace rodfab::common
