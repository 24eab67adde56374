// SHA-256 checksums (OpenSSL EVP), the one implementation every stage uses: job files and their
// manifest, calibration data and calibration files, the design and calibration a job names.
//
// Digests are returned as 64 lowercase hex digits. Errors (OpenSSL unable to provide SHA-256) are
// std::runtime_error. The functions are reentrant. Streamed data: common::FileHasher
// (common/file_hasher.hpp).
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

}  // namespace rodfab::common
