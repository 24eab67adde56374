// Fitting a calibration to DMA measurements.
#pragma once

#include "calibration/data.hpp"
#include "calibration/model.hpp"

#include <stdexcept>

namespace rodfab::calibration {

struct FitOptions {
  Model model = Model::Pchip;
  double floorMpa = kDefaultFloorMpa;
};

// The data cannot be fitted as asked; the message says why (naming fractions or lines) and what to do.
class FitError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

// Fits E(f) to the measurements, all in ln E:
// - the data must hold coupons at f = 0 and f = 1 (the curve is never extrapolated), of one ditherer,
//   with DMA temperatures within 1 C of each other;
// - pchip interpolates the per-fraction means (means of ln E) and refuses means that do not strictly
//   increase with f;
// - lichtenecker and log-power take E_T and E_V from the means at f = 0 and f = 1 and fit their
//   exponent by least squares over every measurement (a coarse scan, then Brent's method around the
//   best scan point); they need three distinct fractions.
// Throws FitError.
Calibration fitCalibration(const DataSet& data, const FitOptions& options = {});

}  // namespace rodfab::calibration
