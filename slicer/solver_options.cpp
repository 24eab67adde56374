#include "slicer/solver_options.hpp"

#include "geometry/nurbs.hpp"

namespace rodfab::cli {

namespace {

// The basis options checked; false after a usage error.
bool readDiscretization(const std::string& command, const po::variables_map& vm, mechanics::Discretization& d) {
  d.degree = vm["degree"].as<int>(), d.spans = vm["spans"].as<int>(), d.refine = vm["refine"].as<int>();
  if (d.degree != 0 && (d.degree < 2 || d.degree > geometry::kMaxDegree))
    return usageError(command, "--degree: expected 0 (keep the design's) or 2.." + std::to_string(geometry::kMaxDegree)), false;
  if (d.spans < 0 || d.spans > mechanics::kMaxSpansPerRod)
    return usageError(command, "--spans: expected 0.." + std::to_string(mechanics::kMaxSpansPerRod)), false;
  if (d.spans > 0 && d.degree == 0)
    return usageError(command, "--spans goes with a --degree; on the design's basis use --refine"), false;
  if (d.refine < -1 || d.refine > 1000) return usageError(command, "--refine: expected -1 (automatic) or 0..1000"), false;
  if (d.refine >= 0 && d.degree != 0)
    return usageError(command, "--refine goes with --degree 0 (the design's basis); use --spans"), false;
  return true;
}

bool readAccuracy(const std::string& command, const po::variables_map& vm, mechanics::AccuracyOptions& a) {
  a.tolerance = vm["accuracy"].as<double>();
  a.maxRefinements = vm["max-refinements"].as<int>();
  a.estimate = vm.count("no-estimate") == 0;
  // Below 1e-8 of the largest displacement the estimate is round-off (Newton stops at 1e-10 of the
  // residual) and the spans it asks for pass kMaxSpansPerRod: refused here, not after the set-up.
  if (!(a.tolerance >= 1e-8) || a.tolerance > 0.1) return usageError(command, "--accuracy: expected a number from 1e-8 to 0.1"), false;
  if (a.maxRefinements < 0 || a.maxRefinements > 6) return usageError(command, "--max-refinements: expected 0..6"), false;
  return true;
}

bool readSolver(const std::string& command, const po::variables_map& vm, mechanics::SolverOptions& s) {
  s.loadSteps = vm["load-steps"].as<int>();
  s.tolerance = vm["tolerance"].as<double>();
  s.maxIterations = vm["max-iterations"].as<int>();
  s.followStableBranch = vm.count("follow-stable-branch") > 0;
  if (s.loadSteps < 0 || s.loadSteps > mechanics::kMaxLoadSteps)
    return usageError(command, "--load-steps: expected 0 (the design's) to " + std::to_string(mechanics::kMaxLoadSteps)), false;
  if (!(s.tolerance > 0) || s.tolerance > 1e-2) return usageError(command, "--tolerance: expected a number in (0, 0.01]"), false;
  if (s.maxIterations < 1 || s.maxIterations > 1000) return usageError(command, "--max-iterations: expected 1..1000"), false;
  return true;
}

}  // namespace

void addSolverOptions(po::options_description& options) {
  options.add_options()
      ("degree", po::value<int>()->default_value(6)->value_name("N"),
       "B-spline degree of the solver's basis (even degrees converge best); 0 keeps each centerline's own NURBS")
      ("spans", po::value<int>()->default_value(0)->value_name("N"),
       "knot spans per rod (0: automatic, from each rod's slenderness, drawn curvature and modulus field)")
      ("refine", po::value<int>()->default_value(-1)->value_name("N"),
       "with --degree 0: knots inserted into every span of the design's centerlines (-1: automatic)")
      ("accuracy", po::value<double>()->default_value(1e-4)->value_name("TOL"),
       "target for the estimated position error over the largest displacement; a warning when above")
      ("max-refinements", po::value<int>()->default_value(2)->value_name("N"), "doublings of every rod's spans while above --accuracy")
      ("no-estimate", "solve once on the basis as chosen: no error estimate, no refinement")
      ("follow-stable-branch", "after a bifurcation, perturb along the critical mode and continue on the stable branch")
      ("load-steps", po::value<int>()->default_value(0)->value_name("N"), "load steps (0: the design's mechanics.load_steps)")
      ("tolerance", po::value<double>()->default_value(1e-10)->value_name("TOL"), "Newton tolerance on the scaled residual or correction")
      ("max-iterations", po::value<int>()->default_value(30)->value_name("N"), "Newton iterations per load step before the step is cut");
}

std::optional<SolverSettings> solverSettings(const std::string& command, const po::variables_map& vm) {
  SolverSettings s;
  if (!readDiscretization(command, vm, s.discretization) || !readAccuracy(command, vm, s.accuracy) ||
      !readSolver(command, vm, s.solver))
    return std::nullopt;
  return s;
}

}  // namespace rodfab::cli
