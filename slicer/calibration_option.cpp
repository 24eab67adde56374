#include "slicer/calibration_option.hpp"

#include "materials/ditherer.hpp"
#include "slicer/calibration_materials.hpp"

#include <filesystem>
#include <iostream>

namespace rodfab::cli {

void addCalibrationOptions(po::options_description& options) {
  options.add_options()
      ("calibration", po::value<std::string>()->value_name("CAL.json"), "calibration file (rodfab calibrate); default: the bundled 60 C fit")
      ("allow-calibration-materials-mismatch",
       "use a calibration measured on other materials than the profile's (the job's moduli are then estimates)");
}

std::optional<ChosenCalibration> calibrationFromOptions(const std::string& command, const po::variables_map& vm,
                                                        const printer_profiles::Profile& profile) {
  const bool chosen = vm.count("calibration") > 0;
  const std::string file = chosen ? vm["calibration"].as<std::string>() : calibration::defaultCalibrationPath().string();
  std::string sha256;
  calibration::Calibration cal = calibration::readCalibration(file, &sha256);
  const std::string fileName = std::filesystem::path(file).filename().string();
  const slicer::CalibrationMaterialsCheck check = slicer::checkCalibrationMaterials(
      // By file name: the message also goes into the manifest, which holds no path of this machine.
      cal, fileName, profile, !chosen, vm.count("allow-calibration-materials-mismatch") > 0);
  if (check.refused) {
    std::cerr << "rodfab " << command << ": " << check.message << "\nno job was written\n";
    return std::nullopt;
  }
  const std::string& recorded = cal.record().dither;  // empty: the data named no ditherer (an optional column)
  if (!recorded.empty() && !materials::isDitherMethod(recorded)) {
    // The default ditherer comes from this field: a bad one is the file's fault, not the command line's.
    std::cerr << "rodfab " << command << ": " << file << ": dither: unknown ditherer '" << cal.record().dither
              << "' (the coupons' ditherer), expected one of: " << materials::ditherMethodList() << "\nno job was written\n";
    return std::nullopt;
  }
  const std::string couponDither = recorded.empty() ? "" : materials::canonicalDitherName(recorded);
  return ChosenCalibration{std::move(cal), file, fileName, sha256, check.message, couponDither};
}

}  // namespace rodfab::cli
