// optimize/: time to optimize E(s) on buckling springs of the published examples' size (34 and 312
// rods, 4 modulus controls per rod: 136 and 1,248 design variables), on a manufactured problem:
// the target is the spring's shape under its training load (clamped bottom ring, top ring moved
// down by 5 %) with a random modulus field between 8 and 190 MPa, and the optimizer starts from a
// uniform 60 MPa. Degree-4 rods of 6 spans (bench_mechanics' fixed discretization). One
// optimization per benchmark run (Iterations(1)); items are optimizer iterations.
#include "examples/example_designs.hpp"
#include "optimize/optimize.hpp"

#include <benchmark/benchmark.h>

#include <sys/resource.h>

#include <random>
#include <set>

using namespace rodfab;
using geometry::Vec3;

namespace {

double peakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

// The spring with one load case: every bottom rod end clamped, every top one moved down by 5 % of
// the height (by point, as a design file gives them).
geometry::RodStructure spring(int around, int levels) {
  examples::SpringParameters p;
  p.nodesAround = around;
  p.levels = levels;
  geometry::RodStructure s = examples::bucklingSpring(p);
  double lo = 1e300, hi = -1e300;
  for (const auto& r : s.rods)
    for (const Vec3& q : {r.centerline().points().front(), r.centerline().points().back()}) lo = std::min(lo, q.z()), hi = std::max(hi, q.z());
  geometry::LoadCase lc;
  lc.name = "compress", lc.path = "mechanics.load_cases[0]", lc.loadSteps = 5;
  std::set<std::tuple<long long, long long, long long>> seen;
  for (const auto& r : s.rods)
    for (const Vec3& q : {r.centerline().points().front(), r.centerline().points().back()}) {
      const bool low = q.z() < lo + 1e-6 * (hi - lo), high = q.z() > hi - 1e-6 * (hi - lo);
      if ((!low && !high) || !seen.insert({std::llround(q.x() * 1e4), std::llround(q.y() * 1e4), std::llround(q.z() * 1e4)}).second) continue;
      geometry::Support support;
      support.at.point = q;
      support.at.path = "bench";
      if (high) support.displacement = Vec3(0, 0, -0.05 * (hi - lo));
      lc.supports.push_back(support);
    }
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
geometry::RodStructure manufactured(int around, int levels) {
  geometry::RodStructure design = spring(around, levels);
  design.mechanics.loadCases[0].target.push_back({design.rods[0].name(), design.rods[0].centerline(), {}, {}, "bench"});
  optimize::DesignProblem generator(design, settings());
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(8.0, 190.0);
  Eigen::VectorXd e(static_cast<Eigen::Index>(generator.variableCount()));
  for (auto& v : e) v = u(rng);
  generator.evaluate(e, false);
  const geometry::RodStructure deformed = generator.caseProblem(0).deformedStructure(generator.state(0));
  auto& target = design.mechanics.loadCases[0].target;
  target.clear();
  for (const auto& r : deformed.rods) target.push_back({r.name(), r.centerline(), r.orientation(), {}, "bench"});
  return design;
}

void optimizeSpring(benchmark::State& state, int around, int levels) {
  const geometry::RodStructure design = manufactured(around, levels);
  optimize::Result last;
  std::size_t rods = 0, unknowns = 0, variables = 0;
  for (auto _ : state) {
    optimize::DesignProblem problem(design, settings());
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
  state.counters["peak_rss_MiB"] = peakRssMb();
}

void optimizeSpring32(benchmark::State& state) { optimizeSpring(state, 4, 3); }
void optimizeSpring312(benchmark::State& state) { optimizeSpring(state, 12, 12); }

}  // namespace

BENCHMARK(optimizeSpring32)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK(optimizeSpring312)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
