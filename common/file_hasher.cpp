#include "common/file_hasher.hpp"

#include "common/xxhash_dispatch.hpp"

#include <openssl/evp.h>

#include <new>
#include <stdexcept>

namespace rodfab::common {

namespace {

std::string lowercaseHex(const unsigned char* bytes, std::size_t length) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex;
  hex.reserve(2 * length);
  for (std::size_t i = 0; i < length; ++i) {
    hex += kHex[bytes[i] >> 4];
    hex += kHex[bytes[i] & 15];
  }
  return hex;
}

XXH3_state_t* xxh(void* p) { return static_cast<XXH3_state_t*>(p); }
EVP_MD_CTX* evp(void* p) { return static_cast<EVP_MD_CTX*>(p); }

}  // namespace

FileHasher::FileHasher(HashAlgorithm algorithm) : algorithm_(algorithm), state_(nullptr) {
  if (algorithm_ == HashAlgorithm::Xxh128) {
    state_ = XXH3_createState();
    if (!state_) throw std::bad_alloc();
    XXH3_128bits_reset(xxh(state_));
    return;
  }
  state_ = EVP_MD_CTX_new();
  if (!state_ || EVP_DigestInit_ex(evp(state_), EVP_sha256(), nullptr) != 1) {
    EVP_MD_CTX_free(evp(state_));
    throw std::runtime_error("SHA-256 unavailable (OpenSSL EVP)");
  }
}

FileHasher::~FileHasher() {
  if (algorithm_ == HashAlgorithm::Xxh128) XXH3_freeState(xxh(state_));
  else EVP_MD_CTX_free(evp(state_));
}

void FileHasher::update(std::span<const std::uint8_t> data) {
  if (algorithm_ == HashAlgorithm::Xxh128) {
    XXH3_128bits_update(xxh(state_), data.data(), data.size());
  } else if (EVP_DigestUpdate(evp(state_), data.data(), data.size()) != 1) {
    throw std::runtime_error("SHA-256 computation failed (OpenSSL EVP_DigestUpdate)");
  }
}

std::string FileHasher::hex() {
  if (algorithm_ == HashAlgorithm::Xxh128) {
    XXH128_canonical_t canonical;  // big-endian, as xxhsum -H2 prints it
    XXH128_canonicalFromHash(&canonical, XXH3_128bits_digest(xxh(state_)));
    return lowercaseHex(canonical.digest, sizeof canonical.digest);
  }
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  if (EVP_DigestFinal_ex(evp(state_), digest, &length) != 1)
    throw std::runtime_error("SHA-256 computation failed (OpenSSL EVP_DigestFinal_ex)");
  return lowercaseHex(digest, length);
}

}  // namespace rodfab::common
