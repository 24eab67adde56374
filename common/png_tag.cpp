#include "common/png_tag.hpp"

#include "common/output_file.hpp"

#include <zlib.h>

#include <cstdint>

namespace rodfab::common {

namespace {

constexpr std::string_view kPngSignature("\x89PNG\r\n\x1a\n", 8);

// The chunk's type and data: "tEXt", "Software", NUL, `software`.
std::string typeAndData(std::string_view software) {
  std::string chunk("tEXtSoftware");
  chunk += '\0';
  chunk.append(software);
  return chunk;
}

void appendBigEndian(std::string& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out += static_cast<char>((v >> shift) & 0xFF);
}

}  // namespace

std::string withSoftwareTag(std::string_view png, std::string_view software) {
  constexpr std::size_t kAfterHeader = 8 + 4 + 4 + 13 + 4;  // signature, IHDR length, type, data, CRC
  if (png.size() < kAfterHeader || png.compare(12, 4, "IHDR") != 0) return std::string(png);
  const std::string body = typeAndData(software);
  std::string out(png.substr(0, kAfterHeader));
  appendBigEndian(out, static_cast<std::uint32_t>(body.size() - 4));
  out.append(body);
  const auto* data = reinterpret_cast<const Bytef*>(body.data());
  appendBigEndian(out, static_cast<std::uint32_t>(::crc32(0L, data, static_cast<uInt>(body.size()))));
  out.append(png.substr(kAfterHeader));
  return out;
}

bool hasSoftwareTag(const std::filesystem::path& file, std::string_view software) {
  return fileStartsWith(file, kPngSignature, typeAndData(software), 128);
}

}  // namespace rodfab::common
