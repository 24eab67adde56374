// mechanics/: Newton time per iteration and per solve at the published examples' sizes (about 34,
// 300 and 400 rods) and beyond 1,000 rods.
//  - spring*: buckling springs (examples::bucklingSpring) clamped at the bottom ring and compressed
//    by 5 % from the top, as degree-4 rods of 6 or 8 spans: the discretization the first solver was
//    measured on (bench/README.md), for per-iteration figures against it.
//  - *Converged: the same structures, the unfolding box's training case and a grid shell through mechanics::simulate with the default
//    discretization (degree 6, automatic spans), the error estimate and any refinement included:
//    what `rodfab simulate` costs.
// Items are Newton iterations.
#include "bench/bench_fixtures.hpp"
#include "examples/example_designs.hpp"
#include "mechanics/mechanics.hpp"

#include <benchmark/benchmark.h>

#include <cmath>

using namespace rodfab;
using geometry::Vec3;

namespace {

// Clamps every rod end at the lowest `axis` coordinate and moves every end at the highest by
// `displacement`: a training load of the kind the published examples use.
mechanics::Design withTrainingLoad(mechanics::Design s, int axis, const Vec3& displacement) {
  s.mechanics.present = true;
  s.mechanics.loadSteps = 5;
  s.mechanics.supports = bench::trainingSupports(s.rods, axis, displacement);
  return s;
}

mechanics::Design spring(int around, int levels) {
  examples::SpringParameters p;
  p.nodesAround = around;
  p.levels = levels;
  const auto s = examples::bucklingSpring(p);
  return withTrainingLoad(mechanics::Design(s), 2, Vec3(0, 0, -0.05 * s.bounds().sizes().z()));
}

// A grid shell of n x n nodes over a 140 mm square, rising 30 mm (z = h (1 - X^2) (1 - Y^2) with X, Y
// in [-1, 1]): 2 n (n - 1) rods of 2 mm diameter, E = 100 MPa, each a quadratic through the surface
// point half-way between its nodes. The boundary nodes are clamped; the interior nodes carry
// 0.12 N downwards each on the 15 x 15 shell (the dome snaps through at about 0.19 N), the same
// total on larger ones (10 load steps).
mechanics::Design gridShell(int n) {
  const double side = 140.0, rise = 30.0;
  auto surface = [&](double X, double Y) { return Vec3(0.5 * side * X, 0.5 * side * Y, rise * (1 - X * X) * (1 - Y * Y)); };
  auto at = [&](int i, int j) { return Vec3(-1.0 + 2.0 * i / (n - 1), -1.0 + 2.0 * j / (n - 1), 0); };
  mechanics::Design s;
  s.source = "grid-shell";
  int index = 0;
  auto addRod = [&](const Vec3& a, const Vec3& b) {  // a, b in (X, Y)
    const Vec3 p0 = surface(a.x(), a.y()), p2 = surface(b.x(), b.y());
    const Vec3 m = surface(0.5 * (a.x() + b.x()), 0.5 * (a.y() + b.y()));
    const geometry::NurbsCurve curve(2, {0, 0, 0, 1, 1, 1}, {p0, 2.0 * m - 0.5 * (p0 + p2), p2});
    s.rods.emplace_back("rod-" + std::to_string(index++), curve, geometry::Section::circle(2.0), std::nullopt, std::nullopt,
                        geometry::CapStyle::Round, geometry::BSplineField::constant(100.0, 0, 1));
  };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j + 1 < n; ++j) addRod(at(i, j), at(i, j + 1)), addRod(at(j, i), at(j + 1, i));
  s.mechanics.present = true;
  s.mechanics.loadSteps = 10;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const Vec3 p = surface(at(i, j).x(), at(i, j).y());
      if (i == 0 || j == 0 || i == n - 1 || j == n - 1) {
        mechanics::Support clamp;
        clamp.at.point = p, clamp.at.path = "bench";
        s.mechanics.supports.push_back(clamp);
      } else {
        mechanics::PointLoad load;
        load.at.point = p, load.at.path = "bench";
        load.force = Vec3(0, 0, -0.12 * std::pow(14.0 / (n - 1), 2));
        s.mechanics.loads.push_back(load);
      }
    }
  return s;
}

void countersFor(benchmark::State& state, const mechanics::StaticProblem& problem, const mechanics::Solution& last,
                 double seconds) {
  state.SetItemsProcessed(state.iterations() * last.newtonIterations);
  state.counters["rods"] = static_cast<double>(problem.rodCount());
  state.counters["unknowns"] = static_cast<double>(problem.unknownCount());
  state.counters["newton_iterations"] = last.newtonIterations;
  state.counters["chord_iterations"] = last.chordIterations;
  state.counters["ms_per_iteration"] = 1e3 * last.totalSeconds / std::max(1, last.newtonIterations);
  state.counters["seconds_per_solve"] = seconds;
  state.counters["assemble_share"] = last.assembleSeconds / last.totalSeconds;
  state.counters["lu_share"] = last.factorizeSeconds / last.totalSeconds;
  state.counters["fresh_factorizations"] = last.factorizations;
  state.counters["pivot_renewals"] = last.pivotRenewals;
  state.counters["peak_rss_MiB"] = bench::peakRssMb();
}

// One path solve on a fixed discretization; per-iteration figures with every step full Newton
// (Arg 0), per-solve figures with chord steps (Arg 1, the default).
void solveFixed(benchmark::State& state, const mechanics::Design& design, int spans) {
  mechanics::Discretization d;
  d.degree = 4, d.spans = spans;
  const mechanics::StaticProblem problem(design, d);
  mechanics::SolverOptions options;
  options.chordSteps = state.range(0) != 0;
  mechanics::Solution last;
  for (auto _ : state) {
    last = mechanics::solve(problem, options, design.mechanics.loadSteps);
    benchmark::DoNotOptimize(last.state.data());
  }
  countersFor(state, problem, last, last.totalSeconds);
}

// What `rodfab simulate` does: default discretization, path, error estimate, refinements.
void simulateConverged(benchmark::State& state, const mechanics::Design& design) {
  mechanics::Simulation last;
  for (auto _ : state) {
    last = mechanics::simulate(design, {}, {}, design.mechanics.loadSteps);
    benchmark::DoNotOptimize(last.solution.state.data());
  }
  countersFor(state, *last.problem, last.solution, last.seconds);
  state.counters["refinements"] = last.refinements;
  state.counters["estimated_relative_error"] = last.estimate.relative;
}

// A 4 x 3 spring: the size of the unfolding box (34 rods).
const mechanics::Design& spring32() { static const auto s = spring(4, 3); return s; }
const mechanics::Design& spring312() { static const auto s = spring(12, 12); return s; }
const mechanics::Design& spring390() { static const auto s = spring(15, 12); return s; }
const mechanics::Design& spring1008() { static const auto s = spring(24, 20); return s; }
const mechanics::Design& shell420() { static const auto s = gridShell(15); return s; }
const mechanics::Design& shell1012() { static const auto s = gridShell(23); return s; }

void bucklingSpring32(benchmark::State& state) { solveFixed(state, spring32(), 8); }
void bucklingSpring312(benchmark::State& state) { solveFixed(state, spring312(), 6); }
void bucklingSpring390(benchmark::State& state) { solveFixed(state, spring390(), 6); }
void bucklingSpring1008(benchmark::State& state) { solveFixed(state, spring1008(), 6); }
void bucklingSpring32Converged(benchmark::State& state) { simulateConverged(state, spring32()); }
// The bundled unfolding box and its training case: 20 T-joints (hinge ends on the squares' edges).
void unfoldingBoxConverged(benchmark::State& state) {
  static const mechanics::Design box = [] {
    mechanics::Design s(examples::unfoldingBox());
    s.mechanics = examples::unfoldingBoxTraining();
    return s;
  }();
  simulateConverged(state, box);
}
void bucklingSpring312Converged(benchmark::State& state) { simulateConverged(state, spring312()); }
void bucklingSpring390Converged(benchmark::State& state) { simulateConverged(state, spring390()); }
void bucklingSpring1008Converged(benchmark::State& state) { simulateConverged(state, spring1008()); }
void gridShell420Converged(benchmark::State& state) { simulateConverged(state, shell420()); }
void gridShell1012Converged(benchmark::State& state) { simulateConverged(state, shell1012()); }

}  // namespace

BENCHMARK(bucklingSpring32)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(bucklingSpring312)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(bucklingSpring390)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(bucklingSpring1008)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(bucklingSpring32Converged)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(unfoldingBoxConverged)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(bucklingSpring312Converged)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(bucklingSpring390Converged)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(bucklingSpring1008Converged)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(gridShell420Converged)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(gridShell1012Converged)->Unit(benchmark::kMillisecond)->UseRealTime();
