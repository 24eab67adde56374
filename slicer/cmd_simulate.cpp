// rodfab simulate: the mechanics block of a design solved along its load path, with an error
// estimate, stability along the path, and the deformed design written.
#include "geometry/geometry.hpp"
#include "mechanics/mechanics.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <variant>

namespace rodfab::cli {

namespace {

struct SimulateSettings {
  std::string design, output;
  mechanics::Discretization discretization;
  mechanics::SolverOptions solver;
  mechanics::AccuracyOptions accuracy;
  int threads = 0;  // --threads (0: all cores)
  bool json = false;
};

void addSimulateOptions(po::options_description& options) {
  options.add_options()
      ("design", po::value<std::string>()->required(), "design file with a \"mechanics\" block (supports, loads)")
      ("output,o", po::value<std::string>()->required(), "deformed design to write (rodfab.design/1, with orientation splines)")
      ("degree", po::value<int>()->default_value(6),
       "B-spline degree of the solver's basis (even degrees converge best); 0 keeps each centerline's own NURBS")
      ("spans", po::value<int>()->default_value(0),
       "knot spans per rod (0: automatic, from each rod's slenderness, drawn curvature and modulus field)")
      ("refine", po::value<int>()->default_value(-1),
       "with --degree 0: knots inserted into every span of the design's centerlines (-1: automatic)")
      ("accuracy", po::value<double>()->default_value(1e-4),
       "target for the estimated position error over the largest displacement; a warning when above")
      ("max-refinements", po::value<int>()->default_value(2), "doublings of every rod's spans while above --accuracy")
      ("no-estimate", "solve once on the basis as chosen: no error estimate, no refinement")
      ("follow-stable-branch", "after a bifurcation, perturb along the critical mode and continue on the stable branch")
      ("load-steps", po::value<int>()->default_value(0), "load steps (0: the design's mechanics.load_steps)")
      ("tolerance", po::value<double>()->default_value(1e-10), "Newton tolerance on the scaled residual or correction")
      ("max-iterations", po::value<int>()->default_value(30), "Newton iterations per load step before the step is cut")
      ("json", "print the convergence history and summary as JSON on stdout");
  addThreadsOption(options, "they assemble the equations; the result does not depend on their number");
}

// The settings from the command line, or the exit code of a usage error or --help.
std::variant<SimulateSettings, int> parseSimulate(const std::vector<std::string>& args) {
  po::options_description options("options");
  addSimulateOptions(options);
  po::positional_options_description positional;
  positional.add("design", 1);
  po::variables_map vm;
  const char* synopsis = "DESIGN.json --output DEFORMED.json [--degree P] [--spans N] [--accuracy TOL] [--load-steps N]";
  if (auto code = parseOptions("simulate", synopsis, options, positional, args, vm)) return *code;
  SimulateSettings s;
  s.design = vm["design"].as<std::string>(), s.output = vm["output"].as<std::string>();
  mechanics::Discretization& d = s.discretization;
  d.degree = vm["degree"].as<int>(), d.spans = vm["spans"].as<int>(), d.refine = vm["refine"].as<int>();
  if (d.degree != 0 && (d.degree < 2 || d.degree > geometry::kMaxDegree))
    return usageError("simulate", "--degree: expected 0 (keep the design's) or 2.." + std::to_string(geometry::kMaxDegree));
  if (d.spans < 0 || d.spans > mechanics::kMaxSpansPerRod)
    return usageError("simulate", "--spans: expected 0.." + std::to_string(mechanics::kMaxSpansPerRod));
  if (d.spans > 0 && d.degree == 0) return usageError("simulate", "--spans goes with a --degree; on the design's basis use --refine");
  if (d.refine < -1 || d.refine > 1000) return usageError("simulate", "--refine: expected -1 (automatic) or 0..1000");
  if (d.refine >= 0 && d.degree != 0) return usageError("simulate", "--refine goes with --degree 0 (the design's basis); use --spans");
  s.accuracy.tolerance = vm["accuracy"].as<double>();
  s.accuracy.maxRefinements = vm["max-refinements"].as<int>();
  s.accuracy.estimate = vm.count("no-estimate") == 0;
  if (!(s.accuracy.tolerance > 0) || s.accuracy.tolerance > 0.1) return usageError("simulate", "--accuracy: expected a number in (0, 0.1]");
  if (s.accuracy.maxRefinements < 0 || s.accuracy.maxRefinements > 6) return usageError("simulate", "--max-refinements: expected 0..6");
  mechanics::SolverOptions& solver = s.solver;
  solver.loadSteps = vm["load-steps"].as<int>();
  solver.tolerance = vm["tolerance"].as<double>();
  solver.maxIterations = vm["max-iterations"].as<int>();
  solver.followStableBranch = vm.count("follow-stable-branch") > 0;
  if (solver.loadSteps < 0 || solver.loadSteps > 100000) return usageError("simulate", "--load-steps: expected 0 (the design's) to 100000");
  if (!(solver.tolerance > 0) || solver.tolerance > 1e-2) return usageError("simulate", "--tolerance: expected a number in (0, 0.01]");
  if (solver.maxIterations < 1 || solver.maxIterations > 1000) return usageError("simulate", "--max-iterations: expected 1..1000");
  const std::optional<int> threads = threadCount("simulate", vm);
  if (!threads) return kUsage;
  s.threads = *threads;
  s.json = vm.count("json") > 0;
  return s;
}

void printStep(const mechanics::LoadStepReport& r) {
  std::printf("step %3d  load %.4f  Newton:", r.index, r.loadFactor);
  for (double v : r.residuals) std::printf(" %.1e", v);
  std::printf("  (%zu iterations", r.residuals.size() - 1);
  if (r.chordIterations > 0) std::printf(", %d with the previous factorization", r.chordIterations);
  std::printf(")");
  if (r.cuts > 0) std::printf("  [step cut %d time%s: +%.4g]", r.cuts, r.cuts > 1 ? "s" : "", r.increment);
  std::printf("\n");
  std::fflush(stdout);
}

const char* stabilityName(mechanics::Stability s) {
  switch (s) {
    case mechanics::Stability::Stable: return "stable";
    case mechanics::Stability::Unstable: return "unstable";
    case mechanics::Stability::Undetermined: return "undetermined";
  }
  return "?";
}

std::string describe(const mechanics::CriticalPoint& c) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s between load factors %.6g and %.6g%s",
                c.kind == mechanics::CriticalPoint::Kind::Bifurcation ? "bifurcation" : "limit point", c.fromLoad, c.toLoad,
                c.branchSwitched ? " (continued on the stable branch)" : "");
  return buf;
}

// Largest displacement of a centerline point (sampled densely) and the rod it is on.
std::pair<double, std::string> largestDisplacement(const mechanics::Design& design, const mechanics::StaticProblem& problem,
                                                   const Eigen::VectorXd& x) {
  const Eigen::VectorXd& x0 = problem.referenceState();
  double largest = 0;
  std::string where;
  for (std::size_t r = 0; r < problem.rodCount(); ++r) {
    const auto& c = design.rods[r].centerline();
    for (int i = 0; i <= 64; ++i) {
      const double u = c.domainBegin() + (c.domainEnd() - c.domainBegin()) * i / 64;
      const double d = (problem.position(x, r, u) - problem.position(x0, r, u)).norm();
      if (d > largest) largest = d, where = design.rods[r].name();
    }
  }
  return {largest, where};
}

std::string basisSummary(const mechanics::StaticProblem& problem, const mechanics::Discretization& asked) {
  const mechanics::Discretization& d = problem.discretization();
  const auto [lo, hi] = std::minmax_element(d.perRod.begin(), d.perRod.end());
  const std::string range = *lo == *hi ? std::to_string(*lo) : std::to_string(*lo) + ".." + std::to_string(*hi);
  const bool automatic = d.degree > 0 ? asked.spans == 0 : asked.refine < 0;
  const std::string how = automatic ? "automatic" : d.degree > 0 ? "--spans" : "--refine";
  const std::string basis = d.degree > 0 ? "degree " + std::to_string(d.degree) + ", " + range + " spans per rod"
                                         : "the design's own, " + range + " solver spans per design span";
  return basis + " (" + how + "); " + std::to_string(problem.unknownCount()) + " unknowns";
}

nlohmann::json estimateJson(const mechanics::Simulation& sim, const mechanics::AccuracyOptions& accuracy) {
  const mechanics::ErrorEstimate& e = sim.estimate;
  if (!accuracy.estimate) return nullptr;
  nlohmann::json j{{"available", e.available}, {"tolerance", accuracy.tolerance}, {"refinements", sim.refinements}};
  if (!e.available) {
    j["note"] = e.note;
    return j;
  }
  j.update({{"position_error_mm", e.positionError}, {"relative", e.relative}, {"within_tolerance", e.relative <= accuracy.tolerance},
            {"compared_unknowns", e.comparedUnknowns}, {"observed_ratio", e.ratio}});
  return j;
}

nlohmann::json summaryJson(const SimulateSettings& s, const mechanics::Simulation& sim, const nlohmann::json& history,
                           const std::pair<double, std::string>& largest) {
  const mechanics::Solution& sol = sim.solution;
  const mechanics::StaticProblem& p = *sim.problem;
  nlohmann::json critical = nlohmann::json::array();
  for (const auto& c : sol.criticalPoints)
    critical.push_back({{"kind", c.kind == mechanics::CriticalPoint::Kind::Bifurcation ? "bifurcation" : "limit_point"},
                        {"from_load", c.fromLoad}, {"to_load", c.toLoad}, {"load_alignment", c.loadAlignment},
                        {"branch_switched", c.branchSwitched}});
  return {{"design", s.design}, {"output", s.output}, {"rods", p.rodCount()}, {"joints", p.jointCount()},
          {"supports", p.supportCount()}, {"unknowns", p.unknownCount()},
          {"discretization", {{"degree", p.discretization().degree}, {"spans_per_rod", p.discretization().perRod}}},
          {"load_steps", history}, {"newton_iterations", sol.newtonIterations}, {"chord_iterations", sol.chordIterations},
          {"stability", stabilityName(sol.stability)}, {"critical_points", critical},
          {"error_estimate", estimateJson(sim, s.accuracy)},
          {"largest_displacement_mm", largest.first}, {"largest_displacement_rod", largest.second},
          {"seconds", {{"total", sim.seconds}, {"assemble", sol.assembleSeconds}, {"factorize_and_solve", sol.factorizeSeconds}}}};
}

// The summary lines of the text output; warnings (estimate above the tolerance, an unstable or
// undetermined final state) go to stderr.
void printSummary(const SimulateSettings& s, const mechanics::Simulation& sim, const std::pair<double, std::string>& largest) {
  const mechanics::Solution& sol = sim.solution;
  std::printf("converged: %zu load steps, %d Newton iterations (+%d reusing a factorization), %.3f s (assembly %.3f s, "
              "LU %.3f s)\n", sol.steps.size(), sol.newtonIterations, sol.chordIterations, sim.seconds, sol.assembleSeconds,
              sol.factorizeSeconds);
  if (sim.refinements > 0) std::printf("basis:     refined %d time%s: %s\n", sim.refinements, sim.refinements > 1 ? "s" : "",
                                       basisSummary(*sim.problem, s.discretization).c_str());
  const mechanics::ErrorEstimate& e = sim.estimate;
  if (!s.accuracy.estimate) std::printf("accuracy:  not estimated (--no-estimate)\n");
  else if (!e.available) std::printf("accuracy:  no estimate: %s\n", e.note.c_str());
  else std::printf("accuracy:  estimated position error %.3g mm = %.2g of the largest displacement (--accuracy %g)\n",
                   e.positionError, e.relative, s.accuracy.tolerance);
  if (s.accuracy.estimate && (!e.available || e.relative > s.accuracy.tolerance))
    std::fprintf(stderr, "warning: the discretization error may exceed --accuracy %g; give more --spans (or --max-refinements)\n",
                 s.accuracy.tolerance);
  std::printf("stability: %s", stabilityName(sol.stability));
  for (const auto& c : sol.criticalPoints) std::printf("; %s", describe(c).c_str());
  std::printf("\n");
  if (sol.stability == mechanics::Stability::Unstable)
    std::fprintf(stderr, "warning: the final state is an unstable equilibrium (det J changed sign along the path)%s\n",
                 s.solver.followStableBranch ? "" : "; --follow-stable-branch continues on the stable (buckled) branch");
  else if (sol.stability == mechanics::Stability::Undetermined)
    std::fprintf(stderr, "warning: %zu critical points passed: the final state may be unstable\n", sol.criticalPoints.size());
  std::printf("largest displacement: %.6g mm (rod '%s')\n", largest.first, largest.second.c_str());
  std::printf("wrote:     %s\n", s.output.c_str());
}

}  // namespace

int runSimulate(const std::vector<std::string>& args) {
  auto parsed = parseSimulate(args);
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const SimulateSettings& s = std::get<SimulateSettings>(parsed);
  commandLineAccepted();
  const ThreadLimit limit(s.threads);
  const std::optional<mechanics::Design> read = readDesignOrReport(s.design, "nothing was written");
  if (!read) return kFailed;
  const mechanics::Design& design = *read;
  // An existing design is replaced only when rodfab wrote it, and never the input.
  if (!outputAllowed(s.output, {s.design}, {"deformed design", true, "", geometry::isDesignFile})) return kFailed;
  if (!s.json)
    std::printf("design:    %s: %zu rods\n", s.design.c_str(), design.rods.size());
  nlohmann::json history = nlohmann::json::array();
  mechanics::Simulation sim;
  try {
    auto onStep = [&](const mechanics::LoadStepReport& r, const Eigen::VectorXd&) {
      history.push_back({{"step", r.index}, {"load_factor", r.loadFactor}, {"increment", r.increment},
                         {"residuals", r.residuals}, {"chord_iterations", r.chordIterations}, {"cuts", r.cuts},
                         {"det_sign", r.determinantSign}});
      if (!s.json) printStep(r);
    };
    auto onLevel = [&](mechanics::Level level, const mechanics::StaticProblem& p) {
      if (s.json) return;
      if (level == mechanics::Level::Path)
        std::printf("structure: %zu joints, %zu supports\nbasis:     %s\n", p.jointCount(), p.supportCount(),
                    basisSummary(p, s.discretization).c_str());
      else if (level == mechanics::Level::Estimate)
        std::printf("estimate:  solving with half the spans (%zu unknowns)\n", p.unknownCount());
      else
        std::printf("refining:  every rod's spans doubled (%zu unknowns)\n", p.unknownCount());
      std::fflush(stdout);
    };
    const int steps = s.solver.loadSteps > 0 ? s.solver.loadSteps : design.mechanics.loadSteps;
    sim = mechanics::simulate(design, s.discretization, s.solver, steps, s.accuracy, onStep, onLevel);
  } catch (const mechanics::MechanicsError& e) {
    std::cerr << e.what() << '\n' << s.design << ": cannot simulate this design; nothing was written\n";
    return kFailed;
  } catch (const mechanics::ConvergenceError& e) {
    std::cerr << e.what() << '\n' << s.design << ": nothing was written\n";
    return kFailed;
  }
  const auto largest = largestDisplacement(design, *sim.problem, sim.solution.state);
  try {
    mechanics::Design deformed = sim.problem->deformedStructure(sim.solution.state);
    deformed.optimize = design.optimize;  // the design's "optimize" block too, so it can be optimized again
    mechanics::writeDesign(deformed, s.output, "deformed by rodfab simulate from " + s.design);
  } catch (const std::exception& e) {
    std::cerr << s.output << ": cannot write: " << e.what() << '\n';
    return kFailed;
  }
  if (s.json) std::cout << summaryJson(s, sim, history, largest).dump(2) << '\n';
  else printSummary(s, sim, largest);
  return kOk;
}

}  // namespace rodfab::cli
