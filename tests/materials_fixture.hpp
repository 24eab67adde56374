// Shared by the materials tests (test_materials.cpp, test_materials_mapping.cpp,
// test_materials_quality.cpp, test_materials_fused.cpp): OpenVDB initialized before any test, and the voxel they assume.
#pragma once

#include "calibration/calibration.hpp"

#include <openvdb/openvdb.h>

namespace rodfab::test {

inline const bool kVdbInitialized = [] {
  openvdb::initialize();
  return true;
}();

// The Connex3 profile's voxel (600 x 300 dpi, 30 um layers), which the numbers in these tests assume.
inline const openvdb::Vec3d kTestVoxel(0.0423, 0.0846, 0.030);

// ln E = ln E_T + ln(E_V / E_T) f^2, so f = sqrt((ln E - ln E_T) / ln(E_V / E_T)) in closed form; E_T =
// 0.5 MPa, E_V = 190 MPa. A floor at E_T (0.5) makes the floor's fraction 0.
inline rodfab::calibration::Calibration logPowerCalibration(double floorMpa = 8.0) {
  rodfab::calibration::ModelParameters p;
  p.model = rodfab::calibration::Model::LogPower;
  p.tangoModulusMpa = 0.5;
  p.veroModulusMpa = 190.0;
  p.exponent = 2.0;
  return rodfab::calibration::Calibration(p, floorMpa);
}

}  // namespace rodfab::test
