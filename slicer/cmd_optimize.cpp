// rodfab optimize: the modulus field E(u) of every rod that trains a design into the target shapes
// of its load cases (optimize/), written as the same design with the optimized moduli.
#include "calibration/calibration.hpp"
#include "common/interrupt.hpp"
#include "geometry/geometry.hpp"
#include "optimize/optimize.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <thread>
#include <variant>

namespace rodfab::cli {

namespace {

struct OptimizeCommand {
  std::string design, output, calibration, plot;
  int modulusControls = 0;  // 0: the design's optimize block, else 4
  int maxIterations = -1;   // -1: the design's optimize block, else 200
  int workers = 1;
  bool json = false;
};

void addOptimizeOptions(po::options_description& options) {
  options.add_options()
      ("design", po::value<std::string>()->required(), "design file with mechanics.load_cases that have a \"target\"")
      ("output,o", po::value<std::string>()->required(), "optimized design to write (the design with the optimized moduli)")
      ("calibration", po::value<std::string>(),
       "calibration file whose floor and stiffest mix bound E (default: the bundled 60 C fit); the design's "
       "optimize.bounds_mpa takes precedence")
      ("modulus-controls", po::value<int>()->default_value(0),
       "B-spline control values of E per rod, 2..64 (0: the design's optimize.modulus_controls, else 4)")
      ("max-iterations", po::value<int>()->default_value(-1),
       "L-BFGS-B iterations, 0..100000 (-1: the design's optimize.max_iterations, else 200)")
      ("threads", po::value<int>()->default_value(0), "worker threads for assembly (0 = all cores)")
      ("plot", po::value<std::string>(), "also write the convergence plot (g/g0 against iteration, log scale) to this PNG")
      ("json", "print a summary as JSON on stdout instead of the progress lines");
}

std::variant<OptimizeCommand, int> parseOptimize(const std::vector<std::string>& args) {
  po::options_description options("options");
  addOptimizeOptions(options);
  po::positional_options_description positional;
  positional.add("design", 1);
  po::variables_map vm;
  const char* synopsis = "DESIGN.json --output OPTIMIZED.json [--calibration CAL.json] [--modulus-controls N] "
                         "[--max-iterations N] [--threads N] [--plot HISTORY.png] [--json]";
  if (auto code = parseOptions("optimize", synopsis, options, positional, args, vm)) return *code;
  OptimizeCommand c;
  c.design = vm["design"].as<std::string>(), c.output = vm["output"].as<std::string>();
  c.calibration = vm.count("calibration") ? vm["calibration"].as<std::string>() : calibration::defaultCalibrationPath().string();
  c.plot = vm.count("plot") ? vm["plot"].as<std::string>() : "";
  if (vm.count("plot") && c.plot.empty()) return usageError("optimize", "--plot: expected a PNG file name");
  if (c.calibration.empty()) return usageError("optimize", "--calibration: expected a calibration file (rodfab calibrate)");
  c.modulusControls = vm["modulus-controls"].as<int>();
  c.maxIterations = vm["max-iterations"].as<int>();
  if (c.modulusControls != 0 && (c.modulusControls < 2 || c.modulusControls > 64))
    return usageError("optimize", "--modulus-controls: expected 2..64 (or 0 for the design's)");
  if (c.maxIterations < -1 || c.maxIterations > 100000) return usageError("optimize", "--max-iterations: expected 0..100000");
  const std::optional<int> threads = threadCount("optimize", vm);
  if (!threads) return kUsage;
  c.workers = *threads > 0 ? *threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  c.json = vm.count("json") > 0;
  return c;
}

// The optimizer's settings: defaults, the calibration's bounds, the design's optimize block, the
// command line, in rising precedence.
optimize::Settings settingsFor(const OptimizeCommand& c, const mechanics::Design& design, const calibration::Calibration& cal) {
  optimize::Settings s;
  s.lowerMpa = cal.floorMpa();
  s.upperMpa = cal.maxModulusMpa();
  optimize::applySpec(design.optimize, s);
  if (c.modulusControls > 0) s.modulusControls = c.modulusControls;
  if (c.maxIterations >= 0) s.maxIterations = c.maxIterations;
  return s;
}

// The optimized design: the input with the new moduli, its mechanics and optimize blocks kept, a
// {"design": PATH} target rewritten relative to the output's folder.
mechanics::Design optimizedDesign(const OptimizeCommand& c, const mechanics::Design& design,
                                       const optimize::DesignProblem& problem, const Eigen::VectorXd& modulus) {
  mechanics::Design out = problem.designWith(modulus);
  namespace fs = std::filesystem;
  const fs::path from = fs::absolute(fs::path(c.design)).parent_path(), to = fs::absolute(fs::path(c.output)).parent_path();
  for (mechanics::LoadCase& lc : out.mechanics.loadCases)
    if (!lc.targetDesign.empty()) lc.targetDesign = fs::path(lc.targetDesign).is_absolute() ? lc.targetDesign
                                                     : (from / lc.targetDesign).lexically_normal().lexically_relative(to).string();
  out.optimize = design.optimize;
  return out;
}

nlohmann::json casesJson(const optimize::Result& r) {
  nlohmann::json cases = nlohmann::json::array();
  for (std::size_t i = 0; i < r.final.cases.size(); ++i) {
    const optimize::CaseObjective &a = r.initial.cases[i], &b = r.final.cases[i];
    cases.push_back({{"name", b.name}, {"weight", b.weight}, {"objective_initial", a.total()}, {"objective_final", b.total()},
                     {"position_final", b.position}, {"curvature_final", b.curvature}});
  }
  return cases;
}

nlohmann::json summaryJson(const OptimizeCommand& c, const optimize::DesignProblem& p, const optimize::Result& r) {
  nlohmann::json history = nlohmann::json::array();
  for (const optimize::Iteration& it : r.history)
    history.push_back({{"iteration", it.index}, {"objective", it.objective}, {"relative", it.relative},
                       {"projected_gradient", it.projectedGradient}, {"newton_iterations", it.newtonIterations},
                       {"seconds", it.seconds}});
  const optimize::Settings& s = p.settings();
  return {{"design", c.design}, {"output", c.output}, {"rods", p.rodCount()}, {"unknowns", p.unknownCount()},
          {"load_cases", p.caseCount()}, {"design_variables", p.variableCount()}, {"modulus_controls", s.modulusControls},
          {"bounds_mpa", {s.lowerMpa, s.upperMpa}}, {"objective_initial", r.initial.objective},
          {"objective_final", r.final.objective},
          {"relative", r.initial.objective > 0 ? r.final.objective / r.initial.objective : 0.0},
          {"iterations", r.iterations}, {"evaluations", r.evaluations}, {"stop_reason", r.stopReason},
          {"modulus_range_mpa", {r.modulus.minCoeff(), r.modulus.maxCoeff()}}, {"cases", casesJson(r)},
          {"history", history}, {"seconds", r.seconds}};
}

void printSummary(const OptimizeCommand& c, const optimize::Result& r) {
  std::printf("result:    g/g0 %.4g (g %.6g -> %.6g) after %d iterations, %d solves per case: %s\n",
              r.initial.objective > 0 ? r.final.objective / r.initial.objective : 0.0, r.initial.objective, r.final.objective,
              r.iterations, r.evaluations, r.stopReason.c_str());
  for (std::size_t i = 0; i < r.final.cases.size(); ++i)
    std::printf("  case %-20s weight %-6g g %.6g -> %.6g\n", ("\"" + r.final.cases[i].name + "\"").c_str(),
                r.final.cases[i].weight, r.initial.cases[i].total(), r.final.cases[i].total());
  std::printf("modulus:   %.4g .. %.4g MPa\ntime:      %.2f s\nwrote:     %s\n", r.modulus.minCoeff(), r.modulus.maxCoeff(),
              r.seconds, c.output.c_str());
  if (!c.plot.empty()) std::printf("plot:      %s\n", c.plot.c_str());
}

// The paths the output must not overwrite: the design and its target designs.
std::vector<std::filesystem::path> inputsOf(const OptimizeCommand& c, const mechanics::Design& design) {
  std::vector<std::filesystem::path> inputs{c.design, c.calibration};
  for (const mechanics::LoadCase& lc : design.mechanics.loadCases)
    if (!lc.targetDesign.empty()) inputs.push_back(std::filesystem::path(c.design).parent_path() / lc.targetDesign);
  return inputs;
}

}  // namespace

int runOptimize(const std::vector<std::string>& args) {
  auto parsed = parseOptimize(args);
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const OptimizeCommand& c = std::get<OptimizeCommand>(parsed);
  commandLineAccepted();
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(c.workers));
  const std::optional<mechanics::Design> read = readDesignOrReport(c.design, "nothing was written");
  if (!read) return kFailed;
  const mechanics::Design& design = *read;
  if (!outputAllowed(c.output, inputsOf(c, design), {"optimized design", true, "", geometry::isDesignFile})) return kFailed;
  std::vector<std::filesystem::path> plotInputs = inputsOf(c, design);
  plotInputs.push_back(c.output);
  if (!c.plot.empty() && !outputAllowed(c.plot, plotInputs, {"convergence plot", true, "", optimize::isHistoryPlot})) return kFailed;
  std::optional<calibration::Calibration> cal;
  try {
    cal = calibration::readCalibration(c.calibration);
  } catch (const std::exception& e) {
    std::cerr << "rodfab optimize: calibration " << c.calibration << ": " << e.what() << "\nnothing was written\n";
    return kFailed;
  }
  const optimize::Settings settings = settingsFor(c, design, *cal);
  if (settings.lowerMpa < cal->floorMpa() || settings.upperMpa > cal->maxModulusMpa())
    std::cerr << "rodfab optimize: warning: optimize.bounds_mpa [" << settings.lowerMpa << ", " << settings.upperMpa
              << "] reaches beyond what " << c.calibration << " can print [" << cal->floorMpa() << ", " << cal->maxModulusMpa()
              << "]: slicing will clamp those moduli\n";
  std::optional<optimize::DesignProblem> problem;
  optimize::Result result;
  try {
    if (design.mechanics.loadCases.empty())
      throw optimize::OptimizeError(c.design + ": mechanics.load_cases: missing; give training cases with a \"target\" shape "
                                    "(the top-level supports and loads alone say what to simulate, not what shape to reach)");
    problem.emplace(design, settings);
    if (!c.json)
      std::printf("design:    %s: %zu rods, %zu load cases, %zu unknowns per case, %zu design variables, E in [%g, %g] MPa\n",
                  c.design.c_str(), problem->rodCount(), problem->caseCount(), problem->unknownCount(), problem->variableCount(),
                  settings.lowerMpa, settings.upperMpa);
    result = optimize::optimize(*problem, [&](const optimize::Iteration& it) {
      common::throwIfInterrupted();
      if (c.json) return;
      std::printf("iter %4d  g/g0 %.4e  |Pg| %.2e  Newton %3d  %8.2f s\n", it.index, it.relative, it.projectedGradient,
                  it.newtonIterations, it.seconds);
      std::fflush(stdout);
    });
  } catch (const optimize::OptimizeError& e) {
    std::cerr << e.what() << "\nnothing was written\n";
    return kFailed;
  } catch (const mechanics::MechanicsError& e) {
    std::cerr << e.what() << "\n" << c.design << ": cannot optimize this design; nothing was written\n";
    return kFailed;
  }
  common::throwIfInterrupted();
  try {
    mechanics::writeDesign(optimizedDesign(c, design, *problem, result.modulus), c.output, "optimized by rodfab optimize from " + c.design);
  } catch (const std::exception& e) {
    std::cerr << c.output << ": cannot write: " << e.what() << '\n';
    return kFailed;
  }
  try {
    if (!c.plot.empty()) optimize::writeHistoryPlot(result.history, c.plot, std::filesystem::path(c.design).filename().string());
  } catch (const std::exception& e) {
    std::filesystem::remove(c.output);  // both or neither
    std::cerr << c.plot << ": cannot write: " << e.what() << "\nnothing was written\n";
    return kFailed;
  }
  if (c.json) std::cout << summaryJson(c, *problem, result).dump(2) << '\n';
  else printSummary(c, result);
  return kOk;
}

}  // namespace rodfab::cli
