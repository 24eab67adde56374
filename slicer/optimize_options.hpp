// The command line of rodfab optimize: its options, declared and range-checked in one place, the
// optimizer's settings they give, and the checks that its outputs may be written.
#pragma once

#include "calibration/calibration.hpp"
#include "slicer/options.hpp"
#include "mechanics/mechanics.hpp"
#include "optimize/optimize.hpp"

#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace rodfab::cli {

// What the command line asks for (files as given).
struct OptimizeCommand {
  std::string design, output, calibration, plot, render;  // plot, render: "" when not asked for
  int modulusControls = 0;  // 0: the design's optimize block, else 4
  int maxIterations = -1;   // -1: the design's optimize block, else 200
  int threads = 0;          // --threads (0: all cores)
  bool json = false;
  optimize::Start start;    // --start
  optimize::Scaling scaling = optimize::Scaling::Logarithmic;
  std::optional<optimize::Method> method;  // none: the default (Settings::method)
};

// The command from `args` (the words after "optimize"), or the exit code after a usage error (2,
// printed naming the option: --modulus-controls 0 or 2..64, --max-iterations -1..100000, --scaling
// log|linear, --method lbfgsb|mma|ccsaq, --start design|uniform[=MPa], --plot and --render two
// different non-empty names) or --help (0).
Parsed<OptimizeCommand> parseOptimize(const std::vector<std::string>& args);

// The optimizer's settings: defaults, the calibration's bounds, the design's optimize block, the
// command line, in rising precedence.
optimize::Settings optimizeSettings(const OptimizeCommand& c, const mechanics::Design& design, const calibration::Calibration& cal);

// optimizeSettings with the calibration read from c.calibration; nullopt after printing why it
// cannot be read and "nothing was written". Warns on stderr when the design's optimize.bounds_mpa
// reach beyond what the calibration can print (slicing would clamp those moduli).
std::optional<optimize::Settings> optimizeSettingsOrReport(const OptimizeCommand& c, const mechanics::Design& design);

// --start uniform=MPa checked against the bounds `settings` took from the calibration or the design's
// optimize.bounds_mpa: empty when within them (or not a uniform value), else the message saying which
// bounds it is outside, for a usage error (exit 2: the command line asks what the design does not allow).
std::string startOutsideBounds(const OptimizeCommand& c, const mechanics::Design& design, const optimize::Settings& settings);

// True when every output may be written (outputAllowed): never the design, its target designs, the
// calibration or another output; an existing file only when rodfab wrote it (a design, or a plot or
// render of optimize); false after printing why and "nothing was written".
bool optimizeOutputsAllowed(const OptimizeCommand& c, const mechanics::Design& design);

}  // namespace rodfab::cli
