// Internal to meshing/: what every reader checks of its input file before opening it (mesh_io.cpp's
// readMesh, cad_process.cpp's checkCadFile, cad_rods.cpp's choice of reader). Each check throws
// MeshError naming the file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>

namespace rodfab::meshing::detail {

// The extension of `file`, lower-cased, with its dot: ".stl" for "part.STL"; empty when there is none.
std::string lowerCaseExtension(const std::filesystem::path& file);

// Throws "unknown KIND format '.x': expected .a, .b or .c" (the extension as written) unless
// lowerCaseExtension(file) is one of `extensions` (each lower-case, with its dot).
void requireExtension(const std::filesystem::path& file, std::string_view kind, std::initializer_list<std::string_view> extensions);

// The size of `file` in bytes. Throws when it is not a regular file, cannot be read, or is larger than
// kMaxMeshFileBytes ("larger than 2 GiB" followed by `tooLargeAdvice`, e.g. ": simplify the mesh first").
std::uintmax_t checkedFileSize(const std::filesystem::path& file, std::string_view tooLargeAdvice);

}  // namespace rodfab::meshing::detail
