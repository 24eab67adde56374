// A file's checksum taken as it streams (a job's file checked as it is read), by the algorithm its
// record names: XXH3-128 (common/xxh128.hpp, a job's files since 2026-12-02) or SHA-256
// (common/sha256.hpp: older jobs, designs, calibration). The digest is the one the algorithm's
// one-shot function gives for the same bytes. Errors: std::bad_alloc, or std::runtime_error when
// OpenSSL cannot provide SHA-256. Thread safety: one object must not be used from two threads at once.
#pragma once

#include <cstdint>
#include <span>
#include <string>

namespace rodfab::common {

enum class HashAlgorithm { Xxh128, Sha256 };

class FileHasher {
public:
  explicit FileHasher(HashAlgorithm algorithm);
  ~FileHasher();
  FileHasher(const FileHasher&) = delete;
  FileHasher& operator=(const FileHasher&) = delete;
  void update(std::span<const std::uint8_t> data);
  // Lowercase hex digest of everything given to update(); call once (the object is finished afterwards).
  std::string hex();

private:
  HashAlgorithm algorithm_;
  void* state_;  // XXH3_state_t or EVP_MD_CTX, kept out of this header
};

}  // namespace rodfab::common
