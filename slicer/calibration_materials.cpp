#include "slicer/calibration_materials.hpp"

namespace rodfab::slicer {

using printer_profiles::MaterialRole;

CalibrationMaterialsCheck checkCalibrationMaterials(const calibration::Calibration& calibration, const std::string& calibrationFile,
                                                    const printer_profiles::Profile& profile, bool bundledDefault,
                                                    bool allowMismatch) {
  const calibration::FitRecord& r = calibration.record();
  const std::string rigid = profile.material(MaterialRole::Rigid).name, rubbery = profile.material(MaterialRole::Rubbery).name;
  const std::string wanted = rigid + " / " + rubbery;
  const std::string replace = "print coupons with rodfab coupons --profile " + profile.name + ", measure them and fit them with " +
                              "rodfab calibrate --materials " + rigid + "," + rubbery;
  if (r.rigidMaterial.empty())
    return {false, calibrationFile + " records no materials; it is taken to be measured on " + wanted +
                       " (rodfab calibrate --materials RIGID,RUBBERY records them)"};
  if (r.rigidMaterial == rigid && r.rubberyMaterial == rubbery) return {};
  const std::string measured = r.rigidMaterial + " / " + r.rubberyMaterial;
  if (bundledDefault)
    return {false, "stand-in calibration: the bundled " + calibrationFile + " was measured on " + measured + ", not on the " +
                       profile.name + " profile's " + wanted + "; it is used until measured data exists (" + rubbery +
                       " is taken to mix like the material it succeeds), so the printed moduli are estimates: " + replace};
  const std::string mismatch = calibrationFile + " was measured on " + measured + ", the " + profile.name + " profile prints " +
                               wanted + ": other materials mix to other moduli";
  if (allowMismatch) return {false, mismatch + " (used anyway: --allow-calibration-materials-mismatch)"};
  return {true, mismatch + "; " + replace + ", or use --allow-calibration-materials-mismatch to print with it anyway"};
}

}  // namespace rodfab::slicer
