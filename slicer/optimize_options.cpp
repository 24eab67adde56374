#include "slicer/optimize_options.hpp"

#include "common/quoted_text.hpp"
#include "geometry/geometry.hpp"
#include "mechanics/mechanics_file.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <filesystem>
#include <iostream>

namespace rodfab::cli {

namespace {

void addOptimizeOptions(po::options_description& options) {
  options.add_options()
      ("design", po::value<std::string>()->required()->value_name("DESIGN.json"), "design file with mechanics.load_cases that have a \"target\"")
      ("output,o", po::value<std::string>()->required()->value_name("OPTIMIZED.json"), "optimized design to write (the design with the optimized moduli)")
      ("calibration", po::value<std::string>()->value_name("CAL.json"),
       "calibration file whose floor and stiffest mix bound E (default: the bundled 60 C fit); the design's "
       "optimize.bounds_mpa takes precedence")
      ("modulus-controls", po::value<int>()->default_value(0)->value_name("N"),
       "B-spline control values of E per rod, 2..64 (0: the design's optimize.modulus_controls, else 4)")
      ("max-iterations", po::value<int>()->default_value(-1)->value_name("N"),
       "L-BFGS-B iterations, 0..100000 (-1: the design's optimize.max_iterations, else 200)")
      ("start", po::value<std::string>()->default_value("design")->value_name("design|uniform[=MPa]"),
       "the starting modulus: design (the file's E(s), default) or uniform[=MPa] (one E everywhere, as the published "
       "optimizations start; without a value the geometric mean of the bounds)")
      ("method", po::value<std::string>()->default_value("lbfgsb")->value_name("lbfgsb|mma|ccsaq"),
       "the optimizer: lbfgsb (L-BFGS-B, default), mma or ccsaq (NLopt; an iteration is one evaluation)")
      ("scaling", po::value<std::string>()->default_value("log")->value_name("log|linear"),
       "the optimizer's variables: log (equal steps are equal ratios of E; default) or linear in E")
      ("plot", po::value<std::string>()->value_name("HISTORY.png"), "also write the convergence plot (g/g0 against iteration, log scale) to this PNG")
      ("render", po::value<std::string>()->value_name("SHAPES.png"),
       "also write the shapes to this PNG: per load case the target, the deformed shape with the starting modulus and "
       "with the optimized one, side by side in three views, coloured by E")
      ("json", "print a summary as JSON on stdout instead of the progress lines");
  addThreadsOption(options, "the optimized design is the same for any count");
}

// --scaling, --method and --start into `c`; kOk, or kUsage after saying which is wrong.
int parseChoices(const po::variables_map& vm, OptimizeCommand& c) {
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
  return kOk;
}

}  // namespace

Parsed<OptimizeCommand> parseOptimize(const std::vector<std::string>& args) {
  po::variables_map vm;
  if (auto code = parseOptionsWithInput("optimize", addOptimizeOptions, "design", args, vm)) return *code;
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
  if (const int code = parseChoices(vm, c); code != kOk) return code;
  const std::optional<int> threads = threadCount("optimize", vm);
  if (!threads) return kUsage;
  c.threads = *threads;
  c.json = vm.count("json") > 0;
  return c;
}

optimize::Settings optimizeSettings(const OptimizeCommand& c, const mechanics::Design& design, const calibration::Calibration& cal) {
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

std::optional<optimize::Settings> optimizeSettingsOrReport(const OptimizeCommand& c, const mechanics::Design& design) {
  std::optional<calibration::Calibration> cal;
  try {
    cal = calibration::readCalibration(c.calibration);
  } catch (const std::exception& e) {
    std::cerr << "rodfab optimize: calibration " << c.calibration << ": " << e.what() << "\nnothing was written\n";
    return std::nullopt;
  }
  const optimize::Settings settings = optimizeSettings(c, design, *cal);
  if (settings.lowerMpa < cal->floorMpa() || settings.upperMpa > cal->maxModulusMpa())
    std::cerr << "rodfab optimize: warning: optimize.bounds_mpa [" << settings.lowerMpa << ", " << settings.upperMpa
              << "] reaches beyond what " << c.calibration << " can print [" << cal->floorMpa() << ", " << cal->maxModulusMpa()
              << "]: slicing will clamp those moduli\n";
  return settings;
}

std::string startOutsideBounds(const OptimizeCommand& c, const mechanics::Design& design, const optimize::Settings& settings) {
  if (!c.start.uniform || !(c.start.mpa > 0) || (c.start.mpa >= settings.lowerMpa && c.start.mpa <= settings.upperMpa)) return {};
  using common::exactNumber;
  return "--start uniform=" + exactNumber(c.start.mpa) + ": outside the bounds [" + exactNumber(settings.lowerMpa) + ", " +
         exactNumber(settings.upperMpa) + "] MPa (" +
         (design.optimize.boundsMpa ? c.design + "'s optimize.bounds_mpa" : "the floor and stiffest mix of " + c.calibration) + ")";
}

bool optimizeOutputsAllowed(const OptimizeCommand& c, const mechanics::Design& design) {
  std::vector<std::filesystem::path> inputs{c.design, c.calibration};
  for (const mechanics::LoadCase& lc : design.mechanics.loadCases)
    if (!lc.targetDesign.empty()) inputs.push_back(mechanics::targetDesignFile(lc, c.design));
  if (!outputAllowed(c.output, inputs, {"optimized design", true, "", geometry::isDesignRodfabWrote})) return false;
  inputs.push_back(c.output);
  if (!c.plot.empty() && !outputAllowed(c.plot, inputs, {"convergence plot", true, "", optimize::isHistoryPlot})) return false;
  if (!c.plot.empty()) inputs.push_back(c.plot);
  return c.render.empty() || outputAllowed(c.render, inputs, {"shape render", true, "", optimize::isHistoryPlot});
}

}  // namespace rodfab::cli
