#include "geometry/geometry.hpp"
#include "mechanics/mechanics.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <thread>

namespace rodfab::cli {

int runSimulate(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("design", po::value<std::string>()->required(), "design file with a \"mechanics\" block (supports, loads)")
      ("output,o", po::value<std::string>()->required(), "deformed design to write (rodfab.design/1, with orientation splines)")
      ("degree", po::value<int>()->default_value(4),
       "B-spline degree of the solver's basis (even degrees converge best); 0 keeps each centerline's own NURBS")
      ("spans", po::value<int>()->default_value(0),
       "knot spans per rod (0: the design's spans times refine + 1, at least 8 when --degree rebuilds the rod)")
      ("refine", po::value<int>()->default_value(0), "knots inserted into every span of the design's centerlines")
      ("load-steps", po::value<int>()->default_value(0), "load steps (0: the design's mechanics.load_steps)")
      ("tolerance", po::value<double>()->default_value(1e-10), "Newton tolerance on the scaled residual or correction")
      ("max-iterations", po::value<int>()->default_value(30), "Newton iterations per load step before the step is cut")
      ("threads", po::value<int>()->default_value(0), "worker threads for assembly (0 = all cores)")
      ("json", "print the convergence history and summary as JSON on stdout");
  po::positional_options_description positional;
  positional.add("design", 1);
  po::variables_map vm;
  const char* synopsis = "DESIGN.json --output DEFORMED.json [--degree P] [--spans N] [--refine N] [--load-steps N]";
  if (auto code = parseOptions("simulate", synopsis, options, positional, args, vm)) return *code;

  mechanics::Discretization discretization;
  discretization.degree = vm["degree"].as<int>();
  discretization.spans = vm["spans"].as<int>();
  discretization.refine = vm["refine"].as<int>();
  if (discretization.degree != 0 && (discretization.degree < 2 || discretization.degree > geometry::kMaxDegree))
    return usageError("simulate", "--degree: expected 0 (keep the design's) or 2.." + std::to_string(geometry::kMaxDegree));
  if (discretization.spans < 0 || discretization.spans > 100000) return usageError("simulate", "--spans: expected 0..100000");
  if (discretization.refine < 0 || discretization.refine > 1000) return usageError("simulate", "--refine: expected 0..1000");
  mechanics::SolverOptions solver;
  solver.loadSteps = vm["load-steps"].as<int>();
  solver.tolerance = vm["tolerance"].as<double>();
  solver.maxIterations = vm["max-iterations"].as<int>();
  if (solver.loadSteps < 0 || solver.loadSteps > 10000)
    return usageError("simulate", "--load-steps: expected 0 (the design's) to 10000");
  if (!(solver.tolerance > 0) || solver.tolerance > 1e-2) return usageError("simulate", "--tolerance: expected a number in (0, 0.01]");
  if (solver.maxIterations < 1 || solver.maxIterations > 1000)
    return usageError("simulate", "--max-iterations: expected 1 to 1000");
  const std::optional<int> threads = threadCount("simulate", vm);
  if (!threads) return kUsage;
  const int workers = *threads > 0 ? *threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(workers));
  const bool json = vm.count("json") > 0;

  commandLineAccepted();
  const std::string file = vm["design"].as<std::string>(), output = vm["output"].as<std::string>();
  const std::optional<geometry::RodStructure> read = readDesignOrReport(file, "nothing was written");
  if (!read) return kFailed;
  const geometry::RodStructure& design = *read;
  // An existing design is replaced only when rodfab wrote it, and never the input.
  if (!outputAllowed(output, {file}, {"deformed design", true, "", geometry::isDesignFile})) return kFailed;

  std::unique_ptr<mechanics::StaticProblem> problem;
  try {
    problem = std::make_unique<mechanics::StaticProblem>(design, discretization);
  } catch (const mechanics::MechanicsError& e) {
    std::cerr << e.what() << '\n' << file << ": cannot simulate this design; nothing was written\n";
    return kFailed;
  }
  const int steps = solver.loadSteps > 0 ? solver.loadSteps : design.mechanics.loadSteps;
  if (!json)
    std::printf("design:    %s: %zu rods, %zu joints, %zu supports; %zu unknowns\n", file.c_str(), problem->rodCount(),
                problem->jointCount(), problem->supportCount(), problem->unknownCount());
  nlohmann::json history = nlohmann::json::array();
  mechanics::Solution solution;
  try {
    solution = mechanics::solve(*problem, solver, steps, [&](const mechanics::LoadStepReport& r, const Eigen::VectorXd&) {
      history.push_back({{"step", r.index}, {"load_factor", r.loadFactor}, {"residuals", r.residuals}, {"cuts", r.cuts}});
      if (json) return;
      std::printf("step %3d  load %.4f  Newton:", r.index, r.loadFactor);
      for (double v : r.residuals) std::printf(" %.1e", v);
      std::printf("  (%zu iterations)\n", r.residuals.size() - 1);
      std::fflush(stdout);
    });
  } catch (const mechanics::ConvergenceError& e) {
    std::cerr << e.what() << '\n' << file << ": nothing was written\n";
    return kFailed;
  } catch (const mechanics::MechanicsError& e) {
    std::cerr << e.what() << '\n' << file << ": nothing was written\n";
    return kFailed;
  }

  // Largest displacement of a centerline point (sampled densely) and where.
  const Eigen::VectorXd& x0 = problem->referenceState();
  double largest = 0;
  std::string where;
  for (std::size_t r = 0; r < problem->rodCount(); ++r) {
    const auto& c = design.rods[r].centerline();
    for (int i = 0; i <= 32; ++i) {
      const double u = c.domainBegin() + (c.domainEnd() - c.domainBegin()) * i / 32;
      const double d = (problem->position(solution.state, r, u) - problem->position(x0, r, u)).norm();
      if (d > largest) largest = d, where = design.rods[r].name();
    }
  }

  geometry::RodStructure deformed = problem->deformedStructure(solution.state);
  try {
    geometry::writeDesign(deformed, output, "deformed by rodfab simulate from " + file);
  } catch (const std::exception& e) {
    std::cerr << output << ": cannot write: " << e.what() << '\n';
    return kFailed;
  }
  if (json) {
    nlohmann::json j{{"design", file},
                     {"output", output},
                     {"rods", problem->rodCount()},
                     {"joints", problem->jointCount()},
                     {"supports", problem->supportCount()},
                     {"unknowns", problem->unknownCount()},
                     {"load_steps", history},
                     {"newton_iterations", solution.newtonIterations},
                     {"largest_displacement_mm", largest},
                     {"largest_displacement_rod", where},
                     {"seconds", {{"total", solution.totalSeconds}, {"assemble", solution.assembleSeconds},
                                  {"factorize_and_solve", solution.factorizeSeconds}}}};
    std::cout << j.dump(2) << '\n';
    return kOk;
  }
  std::printf("converged: %zu load steps, %d Newton iterations, %.3f s (assembly %.3f s, LU %.3f s)\n",
              solution.steps.size(), solution.newtonIterations, solution.totalSeconds, solution.assembleSeconds,
              solution.factorizeSeconds);
  std::printf("largest displacement: %.6g mm (rod '%s')\n", largest, where.c_str());
  std::printf("wrote:     %s\n", output.c_str());
  return kOk;
}

}  // namespace rodfab::cli
