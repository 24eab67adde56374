// What `rodfab slice` reports after the job: the summary on stdout (text or --json) and its warnings
// and notes on stderr.
#pragma once

#include "slicer/calibration_option.hpp"
#include "slicer/job_options.hpp"
#include "slicer/slice_design.hpp"

#include <string>

namespace rodfab::cli {

struct SliceSummary {
  std::string designFile;  // as given
  std::size_t rods = 0;
  const printer_profiles::Profile* profile = nullptr;
  const ChosenCalibration* calibration = nullptr;
  std::string ditherer;
  std::uint64_t seed = 0;
  double inputSeconds = 0.0, totalSeconds = 0.0;  // reading the inputs and preparing; the whole command
};

// The summary on stdout (JSON with options.json), then the warnings (calibration materials, thin
// rods, rods without voxels) and, unless options.quiet, the clamped-moduli note on stderr.
void printSliceSummary(const SliceSummary& summary, const slicer::SliceReport& report, const JobCommandOptions& options);

}  // namespace rodfab::cli
