// What rodfab calibrate prints about a fit: its data, model and parameters, the measured (geometric)
// mean and the fitted modulus at every Vero fraction, the floor, the maximum and the fit's quality.
#pragma once

#include "calibration/calibration.hpp"

namespace rodfab::cli {

// The fit's lines and table on stdout.
void printCalibrationFit(const calibration::Calibration& fit);

}  // namespace rodfab::cli
