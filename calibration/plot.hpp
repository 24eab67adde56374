// The fit plot: measurements (every replicate), the fitted E(f) on a log modulus axis, the floor and
// its fraction. PNG, drawn with cairo.
#pragma once

#include "calibration/model.hpp"

#include <filesystem>
#include <string>

namespace rodfab::calibration {

// The plot as PNG bytes (what writeFitPlot writes; job reports embed it). Throws std::runtime_error
// when cairo fails.
std::string renderFitPlot(const Calibration& calibration);

// Written under a temporary name and renamed; throws std::runtime_error naming the file.
// The PNG carries a tEXt chunk "Software: rodfab calibrate".
void writeFitPlot(const Calibration& calibration, const std::filesystem::path& png);

// True when `png` is a regular file written by writeFitPlot (what `calibrate --plot` may replace).
bool isFitPlot(const std::filesystem::path& png);

}  // namespace rodfab::calibration
