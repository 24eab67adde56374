#include "common/png_tag.hpp"

#include "common/output_file.hpp"
#include "common/xxh128.hpp"

#include <zlib.h>

#include <cstdint>
#include <optional>
#include <string>

namespace rodfab::common {

namespace {

constexpr std::string_view kPngSignature("\x89PNG\r\n\x1a\n", 8);

constexpr std::size_t kAfterHeader = 8 + 4 + 4 + 13 + 4;  // signature, IHDR length, type, data, CRC
constexpr std::string_view kSealWord = ", xxh128 ";
constexpr std::size_t kDigestDigits = 32;
constexpr std::size_t kMaxSealedPngBytes = std::size_t{256} << 20;

// The chunk's type and data up to the digest: "tEXt", "Software", NUL, `software`, ", xxh128 ".
std::string typeAndDataBeforeDigest(std::string_view software) {
  std::string chunk("tEXtSoftware");
  chunk += '\0';
  chunk.append(software).append(kSealWord);
  return chunk;
}

void appendBigEndian(std::string& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out += static_cast<char>((v >> shift) & 0xFF);
}

}  // namespace

std::string withSoftwareTag(std::string_view png, std::string_view software) {
  if (png.size() < kAfterHeader || png.compare(12, 4, "IHDR") != 0) return std::string(png);
  const std::string body = typeAndDataBeforeDigest(software) + xxh128Hex(png);
  std::string out(png.substr(0, kAfterHeader));
  appendBigEndian(out, static_cast<std::uint32_t>(body.size() - 4));
  out.append(body);
  const auto* data = reinterpret_cast<const Bytef*>(body.data());
  appendBigEndian(out, static_cast<std::uint32_t>(::crc32(0L, data, static_cast<uInt>(body.size()))));
  out.append(png.substr(kAfterHeader));
  return out;
}

bool hasSoftwareTag(const std::filesystem::path& file, std::string_view software) {
  if (!fileStartsWith(file, kPngSignature, typeAndDataBeforeDigest(software), 128)) return false;  // most files end here, unread
  const std::optional<std::string> png = readRegularFileAtMost(file, kMaxSealedPngBytes);
  const std::string prefix = typeAndDataBeforeDigest(software);
  const std::size_t digestAt = kAfterHeader + 4 + prefix.size(), chunkEnd = digestAt + kDigestDigits + 4;
  if (!png || png->size() < chunkEnd || png->compare(kAfterHeader + 4, prefix.size(), prefix) != 0) return false;
  const std::string_view view(*png);
  const std::string untagged = std::string(view.substr(0, kAfterHeader)).append(view.substr(chunkEnd));
  return view.substr(digestAt, kDigestDigits) == xxh128Hex(untagged);
}

}  // namespace rodfab::common
