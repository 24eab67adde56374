// optimize/: time to optimize E(s) on buckling springs of the published examples' size (34 and 312
// rods, 4 modulus controls per rod: 136 and 1,248 design variables), on a manufactured problem:
// the target is the spring's shape under its training load (clamped bottom ring, top ring moved
// down by 5 %) with a random modulus field between 8 and 190 MPa, and the optimizer starts from a
// uniform 60 MPa. Degree-4 rods of 6 spans (bench_mechanics' fixed discretization). One
// optimization per benchmark run (Iterations(1)); items are optimizer iterations.
//  - optimizeSpring*: rodfab's optimizer (L-BFGS-B, LBFGS++).
//  - mma/ccsaqSpring32: NLopt's MMA and CCSAQ on the same problem, the same scaling (E in [0, 1],
//    g / g0) and as many solves as L-BFGS-B used, for the comparison in optimize/README.md.
#include "bench/bench_fixtures.hpp"
#include "examples/example_designs.hpp"
#include "optimize/optimize.hpp"

#include <benchmark/benchmark.h>
#include <nlopt.hpp>

#include <algorithm>
#include <random>

using namespace rodfab;
using geometry::Vec3;

namespace {

// The spring with one load case: every bottom rod end clamped, every top one moved down by 5 % of
// the height (by point, as a design file gives them).
mechanics::Design spring(int around, int levels) {
  examples::SpringParameters p;
  p.nodesAround = around;
  p.levels = levels;
  mechanics::Design s(examples::bucklingSpring(p));
  const auto [lo, hi] = bench::endRange(s.rods, 2);
  mechanics::LoadCase lc;
  lc.name = "compress", lc.path = "mechanics.load_cases[0]", lc.loadSteps = 5;
  lc.supports = bench::trainingSupports(s.rods, 2, Vec3(0, 0, -0.05 * (hi - lo)));
  for (auto& r : s.rods)
    r = geometry::Rod(r.name(), r.centerline(), r.section(), r.referenceNormal(), r.orientation(), r.caps(),
                      geometry::BSplineField::constant(60.0, r.centerline().domainBegin(), r.centerline().domainEnd()));
  s.mechanics.present = true;
  s.mechanics.loadCases = {lc};
  return s;
}

optimize::Settings settings() {
  optimize::Settings s;
  s.discretization.degree = 4;
  s.discretization.spans = 6;
  s.maxIterations = 300;
  s.objectiveTolerance = 1e-6;
  return s;
}

// The spring's targets: its shapes with a random modulus field.
mechanics::Design manufactured(int around, int levels) {
  mechanics::Design design = spring(around, levels);
  design.mechanics.loadCases[0].target.push_back({design.rods[0].name(), design.rods[0].centerline(), {}, {}, "bench"});
  optimize::DesignProblem generator(design, settings());
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(8.0, 190.0);
  Eigen::VectorXd e(static_cast<Eigen::Index>(generator.variableCount()));
  for (auto& v : e) v = u(rng);
  generator.evaluate(e, false);
  const mechanics::Design deformed = generator.caseProblem(0).deformedStructure(generator.state(0));
  auto& target = design.mechanics.loadCases[0].target;
  target.clear();
  for (const auto& r : deformed.rods) target.push_back({r.name(), r.centerline(), r.orientation(), {}, "bench"});
  return design;
}

void optimizeSpring(benchmark::State& state, int around, int levels, optimize::Scaling scaling = optimize::Scaling::Linear) {
  const mechanics::Design design = manufactured(around, levels);
  optimize::Result last;
  std::size_t rods = 0, unknowns = 0, variables = 0;
  for (auto _ : state) {
    optimize::Settings s = settings();
    s.scaling = scaling;
    optimize::DesignProblem problem(design, s);
    rods = problem.rodCount(), unknowns = problem.unknownCount(), variables = problem.variableCount();
    last = optimize::optimize(problem);
    benchmark::DoNotOptimize(last.modulus.data());
  }
  int newton = 0;
  for (const auto& it : last.history) newton += it.newtonIterations;
  state.SetItemsProcessed(state.iterations() * last.iterations);
  state.counters["rods"] = static_cast<double>(rods);
  state.counters["unknowns"] = static_cast<double>(unknowns);
  state.counters["design_variables"] = static_cast<double>(variables);
  state.counters["iterations"] = last.iterations;
  state.counters["evaluations"] = last.evaluations;
  state.counters["newton_iterations"] = newton;
  state.counters["g_over_g0"] = last.final.objective / last.initial.objective;
  state.counters["seconds"] = last.seconds;
  state.counters["seconds_per_iteration"] = last.seconds / std::max(1, last.iterations);
  state.counters["peak_rss_MiB"] = bench::peakRssMb();
}

// NLopt's gradient-based bounded methods on the same scaled problem, for `evaluations` solves.
void nloptSpring(benchmark::State& state, nlopt::algorithm algorithm, int around, int levels, int evaluations) {
  const mechanics::Design design = manufactured(around, levels);
  double g0 = 0, best = 0;
  int count = 0;
  for (auto _ : state) {
    optimize::DesignProblem problem(design, settings());
    const double lower = problem.settings().lowerMpa, span = problem.settings().upperMpa - lower;
    const Eigen::VectorXd start = problem.startingModulus();
    std::vector<double> t(start.size());
    for (std::size_t i = 0; i < t.size(); ++i) t[i] = (start[static_cast<Eigen::Index>(i)] - lower) / span;
    count = 0, g0 = 0, best = 0;
    auto objective = [&](const std::vector<double>& x, std::vector<double>& grad) {
      Eigen::VectorXd e(static_cast<Eigen::Index>(x.size()));
      for (std::size_t i = 0; i < x.size(); ++i) e[static_cast<Eigen::Index>(i)] = lower + span * std::clamp(x[i], 0.0, 1.0);
      const optimize::Evaluation ev = problem.evaluate(e, !grad.empty());
      if (count++ == 0) g0 = ev.objective, best = ev.objective;
      best = std::min(best, ev.objective);
      for (std::size_t i = 0; i < grad.size(); ++i) grad[i] = ev.gradient[static_cast<Eigen::Index>(i)] * span / g0;
      return ev.objective / g0;
    };
    nlopt::opt opt(algorithm, static_cast<unsigned>(t.size()));
    opt.set_lower_bounds(0.0);
    opt.set_upper_bounds(1.0);
    opt.set_maxeval(evaluations);
    using Objective = decltype(objective);
    opt.set_min_objective(
        [](const std::vector<double>& x, std::vector<double>& grad, void* data) { return (*static_cast<Objective*>(data))(x, grad); },
        &objective);
    double f = 0;
    try {
      opt.optimize(t, f);
    } catch (const nlopt::roundoff_limited&) {  // stopped by rounding: the best point stands
    }
    benchmark::DoNotOptimize(t.data());
  }
  state.counters["evaluations"] = count;
  state.counters["g_over_g0"] = best / g0;
}

void optimizeSpring32(benchmark::State& state) { optimizeSpring(state, 4, 3); }
void optimizeSpring312(benchmark::State& state) { optimizeSpring(state, 12, 12); }
void optimizeSpring32Log(benchmark::State& state) { optimizeSpring(state, 4, 3, optimize::Scaling::Logarithmic); }
void optimizeSpring312Log(benchmark::State& state) { optimizeSpring(state, 12, 12, optimize::Scaling::Logarithmic); }
void mmaSpring32(benchmark::State& state) { nloptSpring(state, nlopt::LD_MMA, 4, 3, 341); }
void ccsaqSpring32(benchmark::State& state) { nloptSpring(state, nlopt::LD_CCSAQ, 4, 3, 341); }

}  // namespace

BENCHMARK(optimizeSpring32)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(optimizeSpring312)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(optimizeSpring32Log)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(optimizeSpring312Log)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(mmaSpring32)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(ccsaqSpring32)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
