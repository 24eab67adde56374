// What rodfab optimize reports: a line per iteration while it runs, then the summary on stdout
// (text, or JSON with the history, the per-case objectives and the error estimates).
#pragma once

#include "optimize/optimize.hpp"
#include "slicer/optimize_options.hpp"

#include <nlohmann/json.hpp>

#include <vector>

namespace rodfab::cli {

// The iteration's progress line on stdout ("iter N  g/g0 ...  |Pg| ...  Newton N  S s"), flushed.
void printOptimizeIteration(const optimize::Iteration& it);

// A finished optimization, as the summary reports it.
struct OptimizeSummary {
  const OptimizeCommand& command;
  const optimize::DesignProblem& problem;
  const optimize::Result& result;
  const std::vector<optimize::CaseAccuracy>& accuracy;  // per case, in the problem's order
};

// The summary as JSON: files, structure, settings, start, objectives (overall and per case, with
// each case's error estimate), iterations, stop reason, modulus range, history and seconds.
nlohmann::json optimizeSummaryJson(const OptimizeSummary& summary);

// The summary lines on stdout: the result, each case's objective and accuracy, the modulus range,
// the time and the files written.
void printOptimizeSummary(const OptimizeSummary& summary);

}  // namespace rodfab::cli
