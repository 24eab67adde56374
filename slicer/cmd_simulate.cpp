// rodfab simulate: the mechanics block of a design solved along its load path, with an error
// estimate, stability along the path, and the deformed design written. The solver's options are
// slicer/solver_options.hpp; what it prints is slicer/simulation_summary.hpp.
#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "geometry/geometry.hpp"
#include "mechanics/mechanics.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"
#include "slicer/simulation_summary.hpp"
#include "slicer/solver_options.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
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

// Refuses (common::OutOfMemory) a level whose solve would not fit in the memory budget, once its
// problem is built and before its Jacobian is assembled or factorized: the solve's peak on top of
// the process's data now (the new problem, what the level before keeps, the libraries' own). A
// refused estimate or refinement level leaves the estimate unavailable or the refinement where it
// was, with the reason as its note (mechanics::simulate); a refused path level ends the command.
class MemoryCheck {
public:
  explicit MemoryCheck(const std::string& design) : design_(design) {}

  void operator()(mechanics::Level level, const mechanics::StaticProblem& p) {
    const std::uint64_t need = common::saturatedBytes(double(common::dataBytesInUse()) + double(p.memoryEstimate().solve));
    peak_ = std::max(peak_, need);
    common::requireMemory(need, {.what = "simulating " + design_ + " (" + levelName(level) + std::to_string(p.unknownCount()) +
                                         " unknowns)",
                                 .remedy = "use a coarser discretization (--spans, --accuracy) or a smaller design, or raise "
                                           "--max-memory if the machine has more"});
  }
  std::uint64_t peak() const { return peak_; }

private:
  static std::string levelName(mechanics::Level level) {
    if (level == mechanics::Level::Estimate) return "half the spans for the error estimate, ";
    if (level == mechanics::Level::Refinement) return "every rod's spans doubled, ";
    return "";
  }
  std::string design_;
  std::uint64_t peak_ = 0;
};

// The simulation along the design's load path, its steps printed (or collected in `history` for
// --json) as they converge; nullopt after printing why it failed.
std::optional<mechanics::Simulation> simulate(const SimulateSettings& s, const mechanics::Design& design, nlohmann::json& history,
                                              MemoryCheck& memory) {
  auto onStep = [&](const mechanics::LoadStepReport& r, const Eigen::VectorXd&) {
    history.push_back(loadStepJson(r));
    if (!s.json) printLoadStep(r);
  };
  auto onLevel = [&](mechanics::Level level, const mechanics::StaticProblem& p) {
    if (!s.json) printSolverLevel(level, p, s.solver.discretization);
    memory(level, p);
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
  MemoryCheck memory(s.design);
  const std::optional<mechanics::Simulation> sim = simulate(s, design, history, memory);
  if (!sim) return kFailed;
  const SimulationSummary summary{s.design, s.output, s.solver, *sim, history,
                                  largestDisplacement(design, *sim->problem, sim->solution.state), memory.peak()};
  try {
    mechanics::Design deformed = sim->problem->deformedStructure(sim->solution.state);
    deformed.optimize = design.optimize;  // the design's "optimize" block too, so it can be optimized again
    mechanics::writeDesign(deformed, s.output, "deformed by rodfab simulate from " + s.design);
  } catch (const common::Interrupted&) {
    throw;
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
