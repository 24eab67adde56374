// mechanics/: Newton time per iteration and per solve at the published examples' sizes (about 34,
// 300 and 400 rods): buckling springs of 32, 312 and 390 degree-4 rods, clamped at the bottom ring
// and compressed by 5 % from the top. Items are Newton iterations.
#include "examples/example_designs.hpp"
#include "mechanics/mechanics.hpp"

#include <benchmark/benchmark.h>

#include <sys/resource.h>

#include <set>

using namespace rodfab;
using geometry::Vec3;

namespace {

double peakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

// Clamps every rod end at the lowest `axis` coordinate and moves every end at the highest by
// `displacement`: a training load of the kind the published examples use.
geometry::RodStructure withTrainingLoad(geometry::RodStructure s, int axis, const Vec3& displacement) {
  double lo = 1e300, hi = -1e300;
  for (const auto& r : s.rods)
    for (const Vec3& p : {r.centerline().points().front(), r.centerline().points().back()})
      lo = std::min(lo, p[axis]), hi = std::max(hi, p[axis]);
  const double tol = 1e-6 * (hi - lo);
  s.mechanics.present = true;
  s.mechanics.loadSteps = 5;
  auto key = [](const Vec3& p) { return std::make_tuple(std::llround(p.x() * 1e4), std::llround(p.y() * 1e4), std::llround(p.z() * 1e4)); };
  std::set<std::tuple<long long, long long, long long>> seen;
  for (const auto& r : s.rods)
    for (const Vec3& p : {r.centerline().points().front(), r.centerline().points().back()}) {
      const bool low = p[axis] < lo + tol, high = p[axis] > hi - tol;
      if ((!low && !high) || !seen.insert(key(p)).second) continue;
      geometry::Support support;
      support.at.point = p;
      support.at.path = "bench";
      if (high) support.displacement = displacement;
      s.mechanics.supports.push_back(support);
    }
  return s;
}

void solveStructure(benchmark::State& state, const geometry::RodStructure& design, int spans) {
  const mechanics::StaticProblem problem(design, {4, 0, spans});
  mechanics::SolverOptions options;
  mechanics::Solution last;
  for (auto _ : state) {
    last = mechanics::solve(problem, options, design.mechanics.loadSteps);
    benchmark::DoNotOptimize(last.state.data());
  }
  state.SetItemsProcessed(state.iterations() * last.newtonIterations);
  state.counters["rods"] = static_cast<double>(problem.rodCount());
  state.counters["unknowns"] = static_cast<double>(problem.unknownCount());
  state.counters["newton_iterations"] = last.newtonIterations;
  state.counters["ms_per_iteration"] = 1e3 * last.totalSeconds / last.newtonIterations;
  state.counters["assemble_share"] = last.assembleSeconds / last.totalSeconds;
  state.counters["lu_share"] = last.factorizeSeconds / last.totalSeconds;
  state.counters["peak_rss_MiB"] = peakRssMb();
}

void bucklingSpring32(benchmark::State& state) {
  // A 4 x 3 spring: the size of the unfolding box (34 rods), whose hinges join edges mid-span
  // (T-joints), which the end-to-end joints of the solver do not model.
  static const auto design = [] {
    examples::SpringParameters p;
    p.nodesAround = 4;
    p.levels = 3;
    auto s = examples::bucklingSpring(p);
    return withTrainingLoad(s, 2, Vec3(0, 0, -0.05 * s.bounds().sizes().z()));
  }();
  solveStructure(state, design, 8);
}

void bucklingSpring312(benchmark::State& state) {
  static const auto design = [] {
    auto s = examples::bucklingSpring();
    return withTrainingLoad(s, 2, Vec3(0, 0, -0.05 * s.bounds().sizes().z()));
  }();
  solveStructure(state, design, 6);
}

void bucklingSpring390(benchmark::State& state) {
  static const auto design = [] {
    examples::SpringParameters p;
    p.nodesAround = 15;
    auto s = examples::bucklingSpring(p);
    return withTrainingLoad(s, 2, Vec3(0, 0, -0.05 * s.bounds().sizes().z()));
  }();
  solveStructure(state, design, 6);
}

}  // namespace

BENCHMARK(bucklingSpring32)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(bucklingSpring312)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(bucklingSpring390)->Unit(benchmark::kMillisecond)->UseRealTime();
