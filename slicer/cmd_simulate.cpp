// rodfab simulate: the mechanics block of a design solved along its load path, with an error
// estimate, stability along the path, and the deformed design written. The solver's options are
// slicer/solver_options.hpp; what it prints is slicer/simulation_summary.hpp.
#include "geometry/geometry.hpp"
#include "mechanics/mechanics.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"
#include "slicer/simulation_summary.hpp"
#include "slicer/solver_options.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <variant>

namespace rodfab::cli {

namespace {

struct SimulateSettings {
  std::string design, output;
  SolverSettings solver;
  int threads = 0;  // --threads (0: all cores)
  bool json = false;
};

// The settings from the command line, or the exit code of a usage error or --help.
Parsed<SimulateSettings> parseSimulate(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("design", po::value<std::string>()->required()->value_name("DESIGN.json"), "design file with a \"mechanics\" block (supports, loads)")
      ("output,o", po::value<std::string>()->required()->value_name("DEFORMED.json"), "deformed design to write (rodfab.design/1, with orientation splines)");
  addSolverOptions(options);
  options.add_options()("json", "print the convergence history and summary as JSON on stdout");
  addThreadsOption(options, "they assemble the equations; the result does not depend on their number");
  po::variables_map vm;
  if (auto code = parseOptionsWithInput("simulate", options, "design", args, vm)) return *code;
  SimulateSettings s;
  s.design = vm["design"].as<std::string>(), s.output = vm["output"].as<std::string>();
  const std::optional<SolverSettings> solver = solverSettings("simulate", vm);
  if (!solver) return kUsage;
  s.solver = *solver;
  const std::optional<int> threads = threadCount("simulate", vm);
  if (!threads) return kUsage;
  s.threads = *threads;
  s.json = vm.count("json") > 0;
  return s;
}

// The simulation along the design's load path, its steps printed (or collected in `history` for
// --json) as they converge; nullopt after printing why it failed.
std::optional<mechanics::Simulation> simulate(const SimulateSettings& s, const mechanics::Design& design, nlohmann::json& history) {
  auto onStep = [&](const mechanics::LoadStepReport& r, const Eigen::VectorXd&) {
    history.push_back(loadStepJson(r));
    if (!s.json) printLoadStep(r);
  };
  auto onLevel = [&](mechanics::Level level, const mechanics::StaticProblem& p) {
    if (!s.json) printSolverLevel(level, p, s.solver.discretization);
  };
  const SolverSettings& o = s.solver;
  const int steps = o.solver.loadSteps > 0 ? o.solver.loadSteps : design.mechanics.loadSteps;
  try {
    return mechanics::simulate(design, o.discretization, o.solver, steps, o.accuracy, onStep, onLevel);
  } catch (const mechanics::MechanicsError& e) {
    std::cerr << e.what() << '\n' << s.design << ": cannot simulate this design; nothing was written\n";
  } catch (const mechanics::ConvergenceError& e) {
    std::cerr << e.what() << '\n' << s.design << ": nothing was written\n";
  }
  return std::nullopt;
}

// The simulation of `design`, the deformed design written and the summary printed; the exit code.
int simulateDesign(const SimulateSettings& s, const mechanics::Design& design) {
  // An existing design is replaced only when rodfab wrote it, and never the input.
  if (!outputAllowed(s.output, {s.design}, {"deformed design", true, "", geometry::isDesignRodfabWrote})) return kFailed;
  if (!s.json)
    std::printf("design:    %s: %zu rods\n", s.design.c_str(), design.rods.size());
  nlohmann::json history = nlohmann::json::array();
  const std::optional<mechanics::Simulation> sim = simulate(s, design, history);
  if (!sim) return kFailed;
  const SimulationSummary summary{s.design, s.output, s.solver, *sim, history,
                                  largestDisplacement(design, *sim->problem, sim->solution.state)};
  try {
    mechanics::Design deformed = sim->problem->deformedStructure(sim->solution.state);
    deformed.optimize = design.optimize;  // the design's "optimize" block too, so it can be optimized again
    mechanics::writeDesign(deformed, s.output, "deformed by rodfab simulate from " + s.design);
  } catch (const std::exception& e) {
    std::cerr << s.output << ": cannot write: " << e.what() << '\n';
    return kFailed;
  }
  if (s.json) std::cout << simulationJson(summary).dump(2) << '\n';
  else printSimulationSummary(summary);
  return kOk;
}

}  // namespace

int runSimulate(const std::vector<std::string>& args) { return runOnDesign(parseSimulate(args), simulateDesign); }

}  // namespace rodfab::cli
