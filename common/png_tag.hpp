// The mark on PNGs rodfab writes (plots): a tEXt chunk "Software" = "rodfab COMMAND" right after
// IHDR, so that a later run can tell the files it may replace (common::OutputPolicy::isOurs).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace rodfab::common {

// `png` (a whole file as cairo or libpng writes it: the signature, then IHDR) with the chunk
// "Software" = `software` inserted after IHDR; `png` unchanged when it does not start that way.
std::string withSoftwareTag(std::string_view png, std::string_view software);

// Whether `file` is a PNG whose first 128 bytes hold the chunk withSoftwareTag adds for `software`.
// False for anything unreadable; never throws.
bool hasSoftwareTag(const std::filesystem::path& file, std::string_view software);

}  // namespace rodfab::common
