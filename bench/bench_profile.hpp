// The printer a benchmark measures for: its voxel size comes from a printer profile, never from a
// constant. $RODFAB_BENCH_PROFILE names a bundled profile or a profile file (default: the bundled
// printer_profiles::kDefaultProfileName), so a benchmark can be run for every printer family.
#pragma once

#include "printer_profiles/profile.hpp"

#include <openvdb/openvdb.h>

#include <cstdlib>
#include <string>

namespace rodfab::bench {

// The profile named by $RODFAB_BENCH_PROFILE (or the default), loaded once per process. Throws
// printer_profiles::ProfileError (or common::DataDirError) when it cannot be loaded.
inline const printer_profiles::Profile& benchProfile() {
  static const printer_profiles::Profile profile = [] {
    const char* name = std::getenv("RODFAB_BENCH_PROFILE");
    return printer_profiles::loadProfile(name && *name ? name : printer_profiles::kDefaultProfileName);
  }();
  return profile;
}

// The benchmark printer's voxel (x, y, z in mm).
inline openvdb::Vec3d benchVoxelMm() {
  const auto& v = benchProfile().voxelSizeMm;
  return openvdb::Vec3d(v[0], v[1], v[2]);
}

}  // namespace rodfab::bench
