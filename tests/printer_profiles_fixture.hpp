// Shared by the printer_profiles tests (tests/test_printer_profiles.cpp, test_printer_jobs.cpp, test_inspect.cpp):
// the bundled Connex3 profile, per-test scratch folders removed when the program ends, whole-file
// reads and writes.
#pragma once

#include "printer_profiles/printer_profiles.hpp"
#include "voxel/printer_grid.hpp"

#include <unistd.h>

#include <cerrno>  // program_invocation_short_name (GNU)
#include <filesystem>
#include <fstream>
#include <iterator>
#include <span>
#include <string>

namespace rodfab::test {

// The transform of a grid in `profile`'s voxels with voxel (0,0,0) centred at `originMm` (voxel's
// printerTransform, the one place rodfab builds it).
inline openvdb::math::Transform::Ptr profileTransform(const printer_profiles::Profile& profile, const openvdb::Vec3d& originMm) {
  return voxel::printerTransform(profile.voxelSize(), originMm);
}

inline const printer_profiles::Profile& connex3() {
  static const printer_profiles::Profile p = printer_profiles::loadProfile("stratasys-objet500-connex3");
  return p;
}

// This process's scratch folder: rodfab-<test program>-<pid> in the temporary directory.
inline std::filesystem::path scratchRoot() {
  return std::filesystem::temp_directory_path() /
         ("rodfab-" + std::string(program_invocation_short_name) + "-" + std::to_string(::getpid()));
}

// Removes this process's scratch folder when the test program ends.
struct ScratchCleanup {
  ~ScratchCleanup() {
    std::error_code ec;
    std::filesystem::remove_all(scratchRoot(), ec);
  }
};
inline ScratchCleanup scratchCleanup;

// A fresh, empty scratch directory per test.
inline std::filesystem::path scratch(const std::string& name) {
  const std::filesystem::path dir = scratchRoot() / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline printer_profiles::Bytes readAll(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return printer_profiles::Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

inline void writeAll(const std::filesystem::path& file, std::span<const std::uint8_t> data) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
}

}  // namespace rodfab::test
