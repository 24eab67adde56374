// What rodfab simulate reports: a line per load step and per solver level while it runs, then the
// summary on stdout (text, or JSON with the convergence history) and its warnings on stderr.
#pragma once

#include "mechanics/mechanics.hpp"
#include "slicer/solver_options.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>

namespace rodfab::cli {

// The step's line on stdout ("step N  load F  Newton: residuals ..."), flushed.
void printLoadStep(const mechanics::LoadStepReport& step);

// The step as the JSON history lists it: step, load_factor, increment, residuals, chord_iterations,
// cuts, det_sign.
nlohmann::json loadStepJson(const mechanics::LoadStepReport& step);

// The line that opens a solver level on stdout (the structure and basis for the first solve, the
// unknowns of the estimate's and of a refinement's solve), flushed. `asked` is the discretization the
// command line asked for (it says whether the spans were chosen automatically).
void printSolverLevel(mechanics::Level level, const mechanics::StaticProblem& problem, const mechanics::Discretization& asked);

// The largest displacement (mm) of a centerline point, sampled at 65 evenly spaced parameters per
// rod, from `problem`'s reference state to `state`, and the name of the rod it is on ("" when
// nothing moved).
struct LargestDisplacement {
  double mm = 0.0;
  std::string rod;
};
LargestDisplacement largestDisplacement(const mechanics::Design& design, const mechanics::StaticProblem& problem,
                                        const Eigen::VectorXd& state);

// A rod whose spans lie below what its degree needs for 1 % (StaticProblem::leastResolvedRod): as
// JSON {rod, degree, spans, spans_needed, relative_error} (null when none), and the warning on stderr,
// prefixed by `context` (e.g. `case "fold": `) and ending with what to do (nothing when none).
// simulate and optimize both say it.
nlohmann::json underResolvedJson(const std::optional<mechanics::UnderResolvedRod>& rod);
void warnUnderResolved(const std::optional<mechanics::UnderResolvedRod>& rod, const std::string& context, const std::string& remedy);

// The stability verdict's word ("stable", "unstable", "undetermined"); a critical point as the
// summary describes it ("limit point between load factors A and B (snap-through: ...)"), and the
// points as JSON {kind, from_load, to_load, crossings, load_alignment, branch_switched, snap_through}.
// simulate and optimize both say them.
const char* stabilityName(mechanics::Stability stability);
std::string describeCriticalPoint(const mechanics::CriticalPoint& point);
nlohmann::json criticalPointsJson(const std::vector<mechanics::CriticalPoint>& points);

// A finished simulation, as the summary reports it.
struct SimulationSummary {
  const std::string& design;  // the files as given
  const std::string& output;
  const SolverSettings& settings;
  const mechanics::Simulation& simulation;
  const nlohmann::json& history;  // loadStepJson of every step
  LargestDisplacement largest;
  std::uint64_t memoryEstimate = 0;  // bytes: the largest level's estimated need (cmd_simulate.cpp)
};

// The summary as JSON: files, structure, discretization, history, iterations, stability, critical
// points, error estimate, largest displacement, times and the memory estimate.
nlohmann::json simulationJson(const SimulationSummary& summary);

// The summary lines on stdout; warnings on stderr when the error estimate is above --accuracy (or
// missing), when a rod is under-resolved (warnUnderResolved) and when the final state is unstable or
// undetermined.
void printSimulationSummary(const SimulationSummary& summary);

}  // namespace rodfab::cli
