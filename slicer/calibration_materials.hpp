// Whether a calibration may map moduli to fractions for a printer profile's materials: a calibration
// is measured on coupons of one rigid-rubbery pair, and another pair mixes to other moduli.
#pragma once

#include "calibration/calibration.hpp"
#include "printer_profiles/profile.hpp"

#include <string>

namespace rodfab::slicer {

struct CalibrationMaterialsCheck {
  bool refused = false;  // the job must not be made (message says why and what to do)
  std::string message;   // the refusal, or a warning for the summary and the manifest ("" when the pair matches)
};

// Compares the pair the calibration records (FitRecord::rigidMaterial, rubberyMaterial) with the
// profile's rigid and rubbery materials. Another pair is refused unless `allowMismatch`, except for the
// bundled calibration used by default (`bundledDefault`: no calibration was chosen), which stands in
// for any pair until the lab has measured its own (warning). A calibration that records no materials
// (written before the field existed) is accepted with a warning. `calibrationFile` names it in messages.
CalibrationMaterialsCheck checkCalibrationMaterials(const calibration::Calibration& calibration, const std::string& calibrationFile,
                                                    const printer_profiles::Profile& profile, bool bundledDefault,
                                                    bool allowMismatch);

}  // namespace rodfab::slicer
