// The mark on PNGs rodfab writes (plots): a tEXt chunk "Software" = "rodfab COMMAND, xxh128 HEX" right
// after IHDR, HEX the XXH3-128 of the file without that chunk, so that a later run can tell the files it
// may replace (common::OutputPolicy::isOurs) from any a person made or changed since, even one that
// began as rodfab's (a plot edited past its first 128 bytes was replaced: a hostile-input review).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace rodfab::common {

// `png` (a whole file as cairo or libpng writes it: the signature, then IHDR) with the chunk
// "Software" = `software` inserted after IHDR; `png` unchanged when it does not start that way.
std::string withSoftwareTag(std::string_view png, std::string_view software);

// Whether `file` (a regular file of at most 256 MiB, no link followed) is a PNG holding the chunk
// withSoftwareTag adds for `software` after IHDR, whose digest is that of the rest of the file. False
// for anything unreadable; never throws.
bool hasSoftwareTag(const std::filesystem::path& file, std::string_view software);

}  // namespace rodfab::common
