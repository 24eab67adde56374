#include "slicer/optimize_summary.hpp"

#include "slicer/simulation_summary.hpp"

#include <algorithm>
#include <cstdio>

namespace rodfab::cli {

namespace {

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
                     {"error_estimate", estimateJson(accuracy.at(i).estimate)},
                     {"under_resolved", underResolvedJson(accuracy.at(i).underResolved)},
                     {"stability", accuracy.at(i).stability ? nlohmann::json(stabilityName(*accuracy.at(i).stability)) : nlohmann::json()},
                     {"critical_points", criticalPointsJson(accuracy.at(i).criticalPoints)}});
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

nlohmann::json historyJson(const std::vector<optimize::Iteration>& iterations) {
  nlohmann::json history = nlohmann::json::array();
  for (const optimize::Iteration& it : iterations)
    history.push_back({{"iteration", it.index}, {"objective", it.objective}, {"relative", it.relative},
                       {"projected_gradient", it.projectedGradient}, {"newton_iterations", it.newtonIterations},
                       {"seconds", it.seconds}});
  return history;
}

const char* methodName(optimize::Method m) {
  return m == optimize::Method::LbfgsB ? "lbfgsb" : m == optimize::Method::Mma ? "mma" : "ccsaq";
}

void printAccuracy(const std::vector<optimize::CaseAccuracy>& accuracy) {
  for (const optimize::CaseAccuracy& a : accuracy) {
    const mechanics::ErrorEstimate& e = a.estimate;
    if (!e.available) std::printf("accuracy:  case \"%s\": no estimate: %s\n", a.name.c_str(), e.note.c_str());
    else std::printf("accuracy:  case \"%s\": estimated position error %.3g mm = %.2g of the largest displacement (%.4g mm)\n",
                     a.name.c_str(), e.positionError, e.relative, e.largestDisplacement);
    // The optimizer keeps one discretization; simulate refines until the estimate meets its default.
    if (const double target = mechanics::AccuracyOptions{}.tolerance; e.available && e.relative > target)
      std::fprintf(stderr, "warning: case \"%s\": the optimum's equilibrium is estimated accurate to %.2g of its displacement, "
                           "above the %.2g simulate refines to; check the optimized design with rodfab simulate\n",
                   a.name.c_str(), e.relative, target);
    warnUnderResolved(a.underResolved, "case \"" + a.name + "\": at the optimum's E(s), ",
                      "simulate the optimized design (its spans chosen for its own E(s)) before trusting its shape");
  }
}

// Per case, what the load path at the optimum met: the trained shape is reached from the drawn one
// under the case's loads, and an optimum past a snap-through or in an unstable state is no design
// (the optimizer's own solves continue from the previous E(s) and see neither).
void printStability(const std::vector<optimize::CaseAccuracy>& accuracy) {
  for (const optimize::CaseAccuracy& a : accuracy) {
    if (!a.stability) continue;
    std::printf("stability: case \"%s\": %s", a.name.c_str(), stabilityName(*a.stability));
    for (const mechanics::CriticalPoint& c : a.criticalPoints) std::printf("; %s", describeCriticalPoint(c).c_str());
    std::printf("\n");
    const bool snaps = std::any_of(a.criticalPoints.begin(), a.criticalPoints.end(), [](const auto& c) { return c.snapThrough; });
    if (snaps || *a.stability != mechanics::Stability::Stable)
      std::fprintf(stderr, "warning: case \"%s\": at the optimum's E(s) the load path %s: the trained shape may not be the one "
                           "the printed part takes; check the optimized design with rodfab simulate\n",
                   a.name.c_str(), snaps ? "snaps through onto another branch"
                                         : *a.stability == mechanics::Stability::Unstable ? "ends in an unstable equilibrium"
                                                                                          : "passes critical points (stability undetermined)");
  }
}

}  // namespace

void printOptimizeIteration(const optimize::Iteration& it) {
  std::printf("iter %4d  g/g0 %.4e  |Pg| %.2e  Newton %3d  %8.2f s\n", it.index, it.relative, it.projectedGradient,
              it.newtonIterations, it.seconds);
  std::fflush(stdout);
}

nlohmann::json optimizeSummaryJson(const OptimizeSummary& summary) {
  const OptimizeCommand& c = summary.command;
  const optimize::DesignProblem& p = summary.problem;
  const optimize::Result& r = summary.result;
  const optimize::Settings& s = p.settings();
  return {{"design", c.design}, {"output", c.output}, {"rods", p.rodCount()}, {"unknowns", p.unknownCount()},
          {"load_cases", p.caseCount()}, {"design_variables", p.variableCount()}, {"modulus_controls", s.modulusControls},
          {"scaling", s.scaling == optimize::Scaling::Logarithmic ? "log" : "linear"}, {"method", methodName(s.method)},
          {"start", c.start.uniform ? nlohmann::json{{"uniform_mpa", optimize::startingModulus(p, c.start)[0]}} : nlohmann::json("design")},
          {"bounds_mpa", {s.lowerMpa, s.upperMpa}}, {"objective_initial", r.initial.objective},
          {"objective_final", r.final.objective},
          {"relative", r.initial.objective > 0 ? r.final.objective / r.initial.objective : 0.0},
          {"iterations", r.iterations}, {"evaluations", r.evaluations}, {"stop_reason", r.stopReason},
          {"line_search_fallbacks", r.lineSearchFallbacks},
          {"modulus_range_mpa", {r.modulus.minCoeff(), r.modulus.maxCoeff()}}, {"cases", casesJson(r, summary.accuracy)},
          {"error_estimate_relative", worstRelativeError(summary.accuracy)}, {"history", historyJson(r.history)},
          {"seconds", r.seconds}};
}

void printOptimizeSummary(const OptimizeSummary& summary) {
  const OptimizeCommand& c = summary.command;
  const optimize::Result& r = summary.result;
  std::printf("result:    g/g0 %.4g (g %.6g -> %.6g) after %d iterations, %d solves per case: %s\n",
              r.initial.objective > 0 ? r.final.objective / r.initial.objective : 0.0, r.initial.objective, r.final.objective,
              r.iterations, r.evaluations, r.stopReason.c_str());
  for (std::size_t i = 0; i < r.final.cases.size(); ++i)
    std::printf("  case %-20s weight %-6g g %.6g -> %.6g\n", ("\"" + r.final.cases[i].name + "\"").c_str(),
                r.final.cases[i].weight, r.initial.cases[i].total(), r.final.cases[i].total());
  printAccuracy(summary.accuracy);
  printStability(summary.accuracy);
  // The fields' control values, which bound E(s) (a B-spline lies in their range) but are not its extremes.
  std::printf("modulus:   control values %.4g .. %.4g MPa (E(s) lies within them)\ntime:      %.2f s\nwrote:     %s\n",
              r.modulus.minCoeff(), r.modulus.maxCoeff(), r.seconds, c.output.c_str());
  if (!c.plot.empty()) std::printf("plot:      %s\n", c.plot.c_str());
  if (!c.render.empty()) std::printf("render:    %s\n", c.render.c_str());
}

}  // namespace rodfab::cli
