// rodfab optimize: the modulus field E(u) of every rod that trains a design into the target shapes
// of its load cases (optimize/), written as the same design with the optimized moduli.
#include "calibration/calibration.hpp"
#include "common/interrupt.hpp"
#include "geometry/geometry.hpp"
#include "optimize/optimize.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <variant>

namespace rodfab::cli {

namespace {

struct OptimizeCommand {
  std::string design, output, calibration, plot, render;
  int modulusControls = 0;  // 0: the design's optimize block, else 4
  int maxIterations = -1;   // -1: the design's optimize block, else 200
  int threads = 0;  // --threads (0: all cores)
  bool json = false;
  optimize::Start start;  // --start
  optimize::Scaling scaling = optimize::Scaling::Logarithmic;
  std::optional<optimize::Method> method;  // none: the default (L-BFGS-B)
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
      ("start", po::value<std::string>()->default_value("design"),
       "the starting modulus: design (the file's E(s), default) or uniform[=MPa] (one E everywhere, as the published "
       "optimizations start; without a value the geometric mean of the bounds)")
      ("method", po::value<std::string>()->default_value("lbfgsb"),
       "the optimizer: lbfgsb (L-BFGS-B, default), mma or ccsaq (NLopt; an iteration is one evaluation)")
      ("scaling", po::value<std::string>()->default_value("log"),
       "the optimizer's variables: log (equal steps are equal ratios of E; default) or linear in E")
      ("plot", po::value<std::string>(), "also write the convergence plot (g/g0 against iteration, log scale) to this PNG")
      ("render", po::value<std::string>(),
       "also write the shapes to this PNG: per load case the target, the deformed shape with the starting modulus and "
       "with the optimized one, side by side in three views, coloured by E")
      ("json", "print a summary as JSON on stdout instead of the progress lines");
  addThreadsOption(options, "the optimized design is the same for any count");
}

std::variant<OptimizeCommand, int> parseOptimize(const std::vector<std::string>& args) {
  po::options_description options("options");
  addOptimizeOptions(options);
  po::positional_options_description positional;
  positional.add("design", 1);
  po::variables_map vm;
  const char* synopsis = "DESIGN.json --output OPTIMIZED.json [--calibration CAL.json] [--modulus-controls N] "
                         "[--max-iterations N] [--start design|uniform[=MPa]] [--method lbfgsb|mma|ccsaq] [--scaling log|linear] [--threads N] [--plot HISTORY.png] [--render SHAPES.png] [--json]";
  if (auto code = parseOptions("optimize", synopsis, options, positional, args, vm)) return *code;
  OptimizeCommand c;
  c.design = vm["design"].as<std::string>(), c.output = vm["output"].as<std::string>();
  c.calibration = vm.count("calibration") ? vm["calibration"].as<std::string>() : calibration::defaultCalibrationPath().string();
  c.plot = vm.count("plot") ? vm["plot"].as<std::string>() : "";
  if (vm.count("plot") && c.plot.empty()) return usageError("optimize", "--plot: expected a PNG file name");
  c.render = vm.count("render") ? vm["render"].as<std::string>() : "";
  if (vm.count("render") && c.render.empty()) return usageError("optimize", "--render: expected a PNG file name");
  if (!c.plot.empty() && c.render == c.plot) return usageError("optimize", "--render and --plot: expected two different files");
  if (c.calibration.empty()) return usageError("optimize", "--calibration: expected a calibration file (rodfab calibrate)");
  c.modulusControls = vm["modulus-controls"].as<int>();
  c.maxIterations = vm["max-iterations"].as<int>();
  if (c.modulusControls != 0 && (c.modulusControls < 2 || c.modulusControls > 64))
    return usageError("optimize", "--modulus-controls: expected 2..64 (or 0 for the design's)");
  if (c.maxIterations < -1 || c.maxIterations > 100000) return usageError("optimize", "--max-iterations: expected 0..100000");
  const std::string scaling = vm["scaling"].as<std::string>();
  if (scaling != "log" && scaling != "linear") return usageError("optimize", "--scaling: expected log or linear, got \"" + scaling + "\"");
  c.scaling = scaling == "log" ? optimize::Scaling::Logarithmic : optimize::Scaling::Linear;
  const std::string method = vm["method"].as<std::string>();
  if (method == "lbfgsb") c.method = optimize::Method::LbfgsB;
  else if (method == "mma") c.method = optimize::Method::Mma;
  else if (method == "ccsaq") c.method = optimize::Method::Ccsaq;
  else return usageError("optimize", "--method: expected lbfgsb, mma or ccsaq, got \"" + method + "\"");
  const std::string start = vm["start"].as<std::string>();
  if (const std::optional<optimize::Start> parsed = optimize::parseStart(start)) c.start = *parsed;
  else return usageError("optimize", "--start: expected design, uniform or uniform=MPa (a modulus > 0), got \"" + start + "\"");
  const std::optional<int> threads = threadCount("optimize", vm);
  if (!threads) return kUsage;
  c.threads = *threads;
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
  s.scaling = c.scaling;
  if (c.method) s.method = *c.method;
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

nlohmann::json estimateJson(const mechanics::ErrorEstimate& e) {
  if (!e.available) return {{"available", false}, {"note", e.note}};
  return {{"available", true}, {"position_error_mm", e.positionError}, {"largest_displacement_mm", e.largestDisplacement},
          {"relative", e.relative}, {"compared_unknowns", e.comparedUnknowns}};
}

nlohmann::json casesJson(const optimize::Result& r, const std::vector<optimize::CaseAccuracy>& accuracy) {
  nlohmann::json cases = nlohmann::json::array();
  for (std::size_t i = 0; i < r.final.cases.size(); ++i) {
    const optimize::CaseObjective &a = r.initial.cases[i], &b = r.final.cases[i];
    cases.push_back({{"name", b.name}, {"weight", b.weight}, {"objective_initial", a.total()}, {"objective_final", b.total()},
                     {"position_final", b.position}, {"curvature_final", b.curvature},
                     {"error_estimate", estimateJson(accuracy.at(i).estimate)}});
  }
  return cases;
}

// The largest relative error estimate over the cases (null when one is unavailable).
nlohmann::json worstRelativeError(const std::vector<optimize::CaseAccuracy>& accuracy) {
  double worst = 0;
  for (const optimize::CaseAccuracy& a : accuracy) {
    if (!a.estimate.available) return nullptr;
    worst = std::max(worst, a.estimate.relative);
  }
  return worst;
}

nlohmann::json summaryJson(const OptimizeCommand& c, const optimize::DesignProblem& p, const optimize::Result& r,
                           const std::vector<optimize::CaseAccuracy>& accuracy) {
  nlohmann::json history = nlohmann::json::array();
  for (const optimize::Iteration& it : r.history)
    history.push_back({{"iteration", it.index}, {"objective", it.objective}, {"relative", it.relative},
                       {"projected_gradient", it.projectedGradient}, {"newton_iterations", it.newtonIterations},
                       {"seconds", it.seconds}});
  const optimize::Settings& s = p.settings();
  return {{"design", c.design}, {"output", c.output}, {"rods", p.rodCount()}, {"unknowns", p.unknownCount()},
          {"load_cases", p.caseCount()}, {"design_variables", p.variableCount()}, {"modulus_controls", s.modulusControls},
          {"scaling", s.scaling == optimize::Scaling::Logarithmic ? "log" : "linear"},
          {"method", s.method == optimize::Method::LbfgsB ? "lbfgsb" : s.method == optimize::Method::Mma ? "mma" : "ccsaq"},
          {"start", c.start.uniform ? nlohmann::json{{"uniform_mpa", optimize::startingModulus(p, c.start)[0]}} : nlohmann::json("design")},
          {"bounds_mpa", {s.lowerMpa, s.upperMpa}}, {"objective_initial", r.initial.objective},
          {"objective_final", r.final.objective},
          {"relative", r.initial.objective > 0 ? r.final.objective / r.initial.objective : 0.0},
          {"iterations", r.iterations}, {"evaluations", r.evaluations}, {"stop_reason", r.stopReason},
          {"modulus_range_mpa", {r.modulus.minCoeff(), r.modulus.maxCoeff()}}, {"cases", casesJson(r, accuracy)},
          {"error_estimate_relative", worstRelativeError(accuracy)}, {"history", history}, {"seconds", r.seconds}};
}

void printAccuracy(const std::vector<optimize::CaseAccuracy>& accuracy) {
  for (const optimize::CaseAccuracy& a : accuracy) {
    const mechanics::ErrorEstimate& e = a.estimate;
    if (!e.available) std::printf("accuracy:  case \"%s\": no estimate: %s\n", a.name.c_str(), e.note.c_str());
    else std::printf("accuracy:  case \"%s\": estimated position error %.3g mm = %.2g of the largest displacement (%.4g mm)\n",
                     a.name.c_str(), e.positionError, e.relative, e.largestDisplacement);
  }
}

void printSummary(const OptimizeCommand& c, const optimize::Result& r, const std::vector<optimize::CaseAccuracy>& accuracy) {
  std::printf("result:    g/g0 %.4g (g %.6g -> %.6g) after %d iterations, %d solves per case: %s\n",
              r.initial.objective > 0 ? r.final.objective / r.initial.objective : 0.0, r.initial.objective, r.final.objective,
              r.iterations, r.evaluations, r.stopReason.c_str());
  for (std::size_t i = 0; i < r.final.cases.size(); ++i)
    std::printf("  case %-20s weight %-6g g %.6g -> %.6g\n", ("\"" + r.final.cases[i].name + "\"").c_str(),
                r.final.cases[i].weight, r.initial.cases[i].total(), r.final.cases[i].total());
  printAccuracy(accuracy);
  std::printf("modulus:   %.4g .. %.4g MPa\ntime:      %.2f s\nwrote:     %s\n", r.modulus.minCoeff(), r.modulus.maxCoeff(),
              r.seconds, c.output.c_str());
  if (!c.plot.empty()) std::printf("plot:      %s\n", c.plot.c_str());
  if (!c.render.empty()) std::printf("render:    %s\n", c.render.c_str());
}

// The paths the output must not overwrite: the design and its target designs.
std::vector<std::filesystem::path> inputsOf(const OptimizeCommand& c, const mechanics::Design& design) {
  std::vector<std::filesystem::path> inputs{c.design, c.calibration};
  for (const mechanics::LoadCase& lc : design.mechanics.loadCases)
    if (!lc.targetDesign.empty()) inputs.push_back(std::filesystem::path(c.design).parent_path() / lc.targetDesign);
  return inputs;
}

// What one run produces: the problem, the optimizer's result, the shapes to render (when asked)
// and the accuracy of the optimum's equilibria.
struct Outcome {
  std::optional<optimize::DesignProblem> problem;
  Eigen::VectorXd start;  // the starting control values
  optimize::Result result;
  std::vector<optimize::ShapeColumns> shapes;
  std::vector<optimize::CaseAccuracy> accuracy;
};

// Every output may be written (checked before any work): never an input or another output.
bool outputsAllowed(const OptimizeCommand& c, const mechanics::Design& design) {
  std::vector<std::filesystem::path> inputs = inputsOf(c, design);
  if (!outputAllowed(c.output, inputs, {"optimized design", true, "", geometry::isDesignFile})) return false;
  inputs.push_back(c.output);
  if (!c.plot.empty() && !outputAllowed(c.plot, inputs, {"convergence plot", true, "", optimize::isHistoryPlot})) return false;
  if (!c.plot.empty()) inputs.push_back(c.plot);
  return c.render.empty() || outputAllowed(c.render, inputs, {"shape render", true, "", optimize::isHistoryPlot});
}

std::optional<optimize::Settings> settingsOrReport(const OptimizeCommand& c, const mechanics::Design& design) {
  std::optional<calibration::Calibration> cal;
  try {
    cal = calibration::readCalibration(c.calibration);
  } catch (const std::exception& e) {
    std::cerr << "rodfab optimize: calibration " << c.calibration << ": " << e.what() << "\nnothing was written\n";
    return std::nullopt;
  }
  const optimize::Settings settings = settingsFor(c, design, *cal);
  if (settings.lowerMpa < cal->floorMpa() || settings.upperMpa > cal->maxModulusMpa())
    std::cerr << "rodfab optimize: warning: optimize.bounds_mpa [" << settings.lowerMpa << ", " << settings.upperMpa
              << "] reaches beyond what " << c.calibration << " can print [" << cal->floorMpa() << ", " << cal->maxModulusMpa()
              << "]: slicing will clamp those moduli\n";
  return settings;
}

// The shapes with the starting modulus, taken at the optimizer's first report (its state then).
void startShapes(const mechanics::Design& design, const optimize::DesignProblem& p, const Eigen::VectorXd& start,
                 std::vector<optimize::ShapeColumns>& shapes) {
  for (std::size_t i = 0; i < p.caseCount(); ++i) {
    const mechanics::LoadCase& lc = design.mechanics.loadCases[i];
    if (!lc.target.empty()) shapes.push_back({lc.name, optimize::drawnTarget(lc.target), optimize::drawnDeformed(p, i, start), {}});
  }
}

void finalShapes(const mechanics::Design& design, Outcome& o) {
  std::size_t k = 0;
  for (std::size_t i = 0; i < o.problem->caseCount(); ++i)
    if (!design.mechanics.loadCases[i].target.empty()) o.shapes.at(k++).optimized = optimize::drawnDeformed(*o.problem, i, o.result.modulus);
}

void printIteration(const optimize::Iteration& it) {
  std::printf("iter %4d  g/g0 %.4e  |Pg| %.2e  Newton %3d  %8.2f s\n", it.index, it.relative, it.projectedGradient,
              it.newtonIterations, it.seconds);
  std::fflush(stdout);
}

// Sets up and runs the optimization, the shapes and the accuracy estimate; kOk, or kFailed after
// saying why.
int runOptimization(const OptimizeCommand& c, const mechanics::Design& design, const optimize::Settings& settings, Outcome& o) {
  try {
    if (design.mechanics.loadCases.empty())
      throw optimize::OptimizeError(c.design + ": mechanics.load_cases: missing; give training cases with a \"target\" shape "
                                    "(the top-level supports and loads alone say what to simulate, not what shape to reach)");
    optimize::DesignProblem& p = o.problem.emplace(design, settings);
    if (!c.json)
      std::printf("design:    %s: %zu rods, %zu load cases, %zu unknowns per case, %zu design variables, E in [%g, %g] MPa\n",
                  c.design.c_str(), p.rodCount(), p.caseCount(), p.unknownCount(), p.variableCount(), settings.lowerMpa, settings.upperMpa);
    o.start = optimize::startingModulus(p, c.start);
    o.result = optimize::optimize(p, [&](const optimize::Iteration& it) {
      common::throwIfInterrupted();
      if (it.index == 0 && !c.render.empty()) startShapes(design, p, o.start, o.shapes);
      if (!c.json) printIteration(it);
    }, o.start);
    if (!c.render.empty()) finalShapes(design, o);
    o.accuracy = p.accuracyAt(o.result.modulus, [] { common::throwIfInterrupted(); });
  } catch (const optimize::OptimizeError& e) {
    std::cerr << e.what() << "\nnothing was written\n";
    return kFailed;
  } catch (const mechanics::MechanicsError& e) {
    std::cerr << e.what() << "\n" << c.design << ": cannot optimize this design; nothing was written\n";
    return kFailed;
  }
  return kOk;
}

// The optimized design, then the plot and the render: all or none of them.
int writeOutputs(const OptimizeCommand& c, const mechanics::Design& design, const Outcome& o) {
  common::throwIfInterrupted();
  try {
    mechanics::writeDesign(optimizedDesign(c, design, *o.problem, o.result.modulus), c.output, "optimized by rodfab optimize from " + c.design);
  } catch (const std::exception& e) {
    std::cerr << c.output << ": cannot write: " << e.what() << '\n';
    return kFailed;
  }
  std::vector<std::string> written{c.output};
  std::string writing;
  try {
    const std::string name = std::filesystem::path(c.design).filename().string();
    if (!c.plot.empty()) writing = c.plot, optimize::writeHistoryPlot(o.result.history, c.plot, name), written.push_back(c.plot);
    const optimize::Settings& s = o.problem->settings();
    if (!c.render.empty()) writing = c.render, optimize::writeShapeRender(o.shapes, s.lowerMpa, s.upperMpa, c.render, name);
  } catch (const common::Interrupted&) {
    throw;  // the cleanup registry removes what was written
  } catch (const std::exception& e) {
    for (const std::string& f : written) std::filesystem::remove(f);  // all or none
    std::cerr << writing << ": cannot write: " << e.what() << "\nnothing was written\n";
    return kFailed;
  }
  return kOk;
}

}  // namespace

int runOptimize(const std::vector<std::string>& args) {
  auto parsed = parseOptimize(args);
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const OptimizeCommand& c = std::get<OptimizeCommand>(parsed);
  commandLineAccepted();
  const ThreadLimit limit(c.threads);
  const std::optional<mechanics::Design> read = readDesignOrReport(c.design, "nothing was written");
  if (!read) return kFailed;
  const mechanics::Design& design = *read;
  if (!outputsAllowed(c, design)) return kFailed;
  const std::optional<optimize::Settings> settings = settingsOrReport(c, design);
  if (!settings) return kFailed;
  Outcome o;
  if (runOptimization(c, design, *settings, o) != kOk || writeOutputs(c, design, o) != kOk) return kFailed;
  if (c.json) std::cout << summaryJson(c, *o.problem, o.result, o.accuracy).dump(2) << '\n';
  else printSummary(c, o.result, o.accuracy);
  return kOk;
}

}  // namespace rodfab::cli
