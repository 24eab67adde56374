// Shared by the materials tests (test_materials.cpp, test_materials_mapping.cpp,
// test_materials_quality.cpp): OpenVDB initialized before any test, and the voxel they assume.
#pragma once

#include <openvdb/openvdb.h>

namespace rodfab::test {

inline const bool kVdbInitialized = [] {
  openvdb::initialize();
  return true;
}();

// The Connex3 profile's voxel (600 x 300 dpi, 30 um layers), which the numbers in these tests assume.
inline const openvdb::Vec3d kTestVoxel(0.0423, 0.0846, 0.030);

}  // namespace rodfab::test
