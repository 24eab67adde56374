// The solver's options, for rodfab simulate: the basis (--degree, --spans, --refine), the error
// estimate (--accuracy, --max-refinements, --no-estimate) and the load path (--load-steps,
// --tolerance, --max-iterations, --follow-stable-branch), declared and range-checked in one place.
#pragma once

#include "mechanics/mechanics.hpp"
#include "slicer/options.hpp"

#include <optional>
#include <string>

namespace rodfab::cli {

// What the options below ask of mechanics::simulate.
struct SolverSettings {
  mechanics::Discretization discretization;  // degree (0: the design's own NURBS), spans (0: automatic), refine
  mechanics::SolverOptions solver;           // loadSteps 0: the design's mechanics.load_steps
  mechanics::AccuracyOptions accuracy;
};

// Declares --degree, --spans, --refine, --accuracy, --max-refinements, --no-estimate,
// --follow-stable-branch, --load-steps, --tolerance and --max-iterations, in this order.
void addSolverOptions(po::options_description& options);

// The settings those options give; nullopt after printing a usage error for `command` naming the first
// option out of range (degree 0 or 2..geometry::kMaxDegree; spans 0..mechanics::kMaxSpansPerRod and
// only with a degree; refine -1..1000 and only with degree 0; accuracy in (0, 0.1]; max-refinements
// 0..6; load-steps 0..100000; tolerance in (0, 0.01]; max-iterations 1..1000).
std::optional<SolverSettings> solverSettings(const std::string& command, const po::variables_map& vm);

}  // namespace rodfab::cli
