// rodfab optimize: the modulus field E(u) of every rod that trains a design into the target shapes
// of its load cases (optimize/), written as the same design with the optimized moduli. The command
// line is slicer/optimize_options.hpp; what it prints is slicer/optimize_summary.hpp.
#include "common/interrupt.hpp"
#include "optimize/optimize.hpp"
#include "slicer/command.hpp"
#include "slicer/optimize_options.hpp"
#include "slicer/optimize_summary.hpp"
#include "slicer/options.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <variant>

namespace rodfab::cli {

namespace {

// What one run produces: the problem, the optimizer's result, the shapes to render (when asked)
// and the accuracy of the optimum's equilibria.
struct Outcome {
  std::optional<optimize::DesignProblem> problem;
  Eigen::VectorXd start;  // the starting control values
  optimize::Result result;
  std::vector<optimize::ShapeColumns> shapes;
  std::vector<optimize::CaseAccuracy> accuracy;
};

// The design's own E(s) starts the run within the bounds: said when that moved it.
void printClampedStart(const mechanics::Design& design, const optimize::Settings& settings) {
  double lowest = std::numeric_limits<double>::infinity(), highest = -lowest;
  for (const geometry::Rod& rod : design.rods)
    for (double v : rod.modulus().values()) lowest = std::min(lowest, v), highest = std::max(highest, v);
  if (lowest < settings.lowerMpa || highest > settings.upperMpa)
    std::printf("start:     the design's E(s) (control values %g .. %g MPa) clamped into the bounds [%g, %g] MPa\n", lowest, highest,
                settings.lowerMpa, settings.upperMpa);
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
    if (!c.json && !c.start.uniform) printClampedStart(design, settings);
    o.result = optimize::optimize(p, [&](const optimize::Iteration& it) {
      common::throwIfInterrupted();
      if (it.index == 0 && !c.render.empty()) o.shapes = optimize::startingShapes(design, p, o.start);
      if (!c.json) printOptimizeIteration(it);
    }, o.start);
    if (!c.render.empty()) optimize::addOptimizedShapes(design, p, o.result.modulus, o.shapes);
    o.accuracy = p.accuracyAt(o.result.modulus, [] { common::throwIfInterrupted(); });
  } catch (const optimize::OptimizeError& e) {
    std::cerr << e.what() << "\n" << c.design << ": nothing was written\n";
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
    mechanics::writeDesign(optimize::optimizedDesign(*o.problem, o.result.modulus, design, c.design, c.output), c.output,
                           "optimized by rodfab optimize from " + c.design);
  } catch (const common::Interrupted&) {
    throw;
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
    for (const std::string& f : written) common::withdrawCommitted(f);  // all or none: what they replaced is back
    std::cerr << writing << ": cannot write: " << e.what() << "\nnothing was written\n";
    return kFailed;
  }
  return kOk;
}

// The optimization of `design`, its outputs written and the summary printed; the exit code.
int optimizeDesign(const OptimizeCommand& c, const mechanics::Design& design) {
  if (!optimizeOutputsAllowed(c, design)) return kFailed;
  const std::optional<optimize::Settings> settings = optimizeSettingsOrReport(c, design);
  if (!settings) return kFailed;
  if (const std::string outside = startOutsideBounds(c, design, *settings); !outside.empty()) return usageError("optimize", outside);
  Outcome o;
  if (runOptimization(c, design, *settings, o) != kOk || writeOutputs(c, design, o) != kOk) return kFailed;
  if (c.json) std::cout << optimizeSummaryJson({c, *o.problem, o.result, o.accuracy}).dump(2) << '\n';
  else printOptimizeSummary({c, *o.problem, o.result, o.accuracy});
  return kOk;
}

}  // namespace

int runOptimize(const std::vector<std::string>& args) { return runOnDesign(parseOptimize(args), optimizeDesign); }

}  // namespace rodfab::cli
