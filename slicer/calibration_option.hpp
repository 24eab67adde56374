// --calibration and --allow-calibration-materials-mismatch, for the commands that map moduli to Vero
// fractions: the calibration file read, checksummed and checked against the profile's materials.
#pragma once

#include "calibration/calibration.hpp"
#include "printer_profiles/profile.hpp"
#include "slicer/options.hpp"

#include <optional>
#include <string>

namespace rodfab::cli {

void addCalibrationOptions(po::options_description& options);

struct ChosenCalibration {
  calibration::Calibration calibration;
  std::string file;      // as given (or the bundled default's path)
  std::string fileName;  // its file name: what jobs record (no path of this machine travels with them)
  std::string sha256;
  std::string materialsWarning;  // slicer::checkCalibrationMaterials's warning ("" when the pair matches)
  // The ditherer its coupons were printed with, canonical (materials::canonicalDitherName); "" if unknown.
  std::string couponDither;
};

// The calibration --calibration names (default: the bundled 60 C fit), checked against `profile`'s
// materials. Prints the refusal, then "no job was written", and returns nullopt when it must not be
// used; a file that cannot be read throws (calibration::CalibrationError, reported by runCommand).
std::optional<ChosenCalibration> calibrationFromOptions(const std::string& command, const po::variables_map& vm,
                                                        const printer_profiles::Profile& profile);

}  // namespace rodfab::cli
