#include "common/quoted_text.hpp"

#include <charconv>
#include <cstdio>

namespace rodfab::common {

namespace {

// The length of the valid UTF-8 character at the start of `s` (its code point in `code`), or 0.
std::size_t utf8Length(std::string_view s, char32_t& code) {
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(s[i]); };
  const unsigned char lead = byte(0);
  std::size_t length = 0;
  char32_t least = 0;
  if (lead < 0x80) return code = lead, 1;
  if (lead >= 0xc2 && lead <= 0xdf) length = 2, code = lead & 0x1f, least = 0x80;
  else if (lead >= 0xe0 && lead <= 0xef) length = 3, code = lead & 0x0f, least = 0x800;
  else if (lead >= 0xf0 && lead <= 0xf4) length = 4, code = lead & 0x07, least = 0x10000;
  else return 0;
  if (s.size() < length) return 0;
  for (std::size_t i = 1; i < length; ++i) {
    if ((byte(i) & 0xc0) != 0x80) return 0;
    code = (code << 6) | (byte(i) & 0x3f);
  }
  const bool surrogate = code >= 0xd800 && code <= 0xdfff;
  return code < least || code > 0x10ffff || surrogate ? 0 : length;
}

void appendEscaped(std::string& out, unsigned char c) {
  char hex[5];
  std::snprintf(hex, sizeof hex, "\\x%02x", c);
  out += hex;
}

bool isControl(char32_t code) { return code < 0x20 || (code >= 0x7f && code <= 0x9f); }

}  // namespace

bool holdsControlCharacters(std::string_view text) {
  for (std::size_t i = 0; i < text.size();) {
    char32_t code = 0;
    const std::size_t length = utf8Length(text.substr(i), code);
    if (length == 0 || isControl(code)) return true;
    i += length;
  }
  return false;
}

std::string printableFromFile(std::string_view text, std::size_t maxBytes) {
  const bool cut = text.size() > maxBytes;
  if (cut) text = text.substr(0, maxBytes);
  std::string out;
  for (std::size_t i = 0; i < text.size();) {
    char32_t code = 0;
    const std::size_t length = utf8Length(text.substr(i), code);
    const bool control = isControl(code) || code == '\'' || code == '\\';
    if (length == 0 || control) {
      // A character of several bytes is escaped byte by byte (a C1 control); an invalid byte alone.
      for (std::size_t b = 0; b < (length == 0 ? 1 : length); ++b) appendEscaped(out, static_cast<unsigned char>(text[i + b]));
      i += length == 0 ? 1 : length;
      continue;
    }
    out.append(text.substr(i, length));
    i += length;
  }
  if (cut) out += "...";
  return out;
}

std::string quotedFromFile(std::string_view text, std::size_t maxBytes) {
  std::string out = "'";
  out += printableFromFile(text, maxBytes);  // not "'" + ...: GCC 12 warns of a false overlap there (-Wrestrict)
  out += '\'';
  return out;
}

std::string exactNumber(double v) {
  char text[32];
  const auto result = std::to_chars(text, text + sizeof text, v);
  return std::string(text, result.ptr);
}

}  // namespace rodfab::common
