// Internal: whole-file writes that a reader never sees half done.
#pragma once

#include <filesystem>
#include <string_view>

namespace rodfab::calibration {

// Writes `bytes` to a temporary name beside `file` and renames it over `file`; on any failure the
// temporary is removed, `file` is left as it was, and std::runtime_error names the file.
void writeFileAtomically(const std::filesystem::path& file, std::string_view bytes);

}  // namespace rodfab::calibration
