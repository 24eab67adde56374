// The fit plot: measurements (every replicate), the fitted E(f) on a log modulus axis, the floor and
// its fraction. PNG, drawn with cairo.
#pragma once

#include "calibration/model.hpp"

#include <filesystem>

namespace rodfab::calibration {

// Written under a temporary name and renamed; throws std::runtime_error naming the file.
void writeFitPlot(const Calibration& calibration, const std::filesystem::path& png);

}  // namespace rodfab::calibration
