#include "mechanics/mechanics.hpp"

#include <Eigen/SparseLU>

#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

namespace rodfab::mechanics {

namespace {

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

std::string format(double v) {
  std::ostringstream s;
  s.precision(4);
  s << v;
  return s.str();
}

enum class Outcome { Converged, Diverged };

}  // namespace

Solution solve(const StaticProblem& problem, const SolverOptions& options, int designLoadSteps,
               const StepCallback& onStep) {
  const auto start = std::chrono::steady_clock::now();
  const int steps = options.loadSteps > 0 ? options.loadSteps : std::max(1, designLoadSteps);
  Solution solution;
  solution.state = problem.referenceState();
  Eigen::SparseMatrix<double> jacobian;
  Eigen::VectorXd residual;
  Eigen::SparseLU<Eigen::SparseMatrix<double>, Eigen::COLAMDOrdering<int>> lu;
  bool analyzed = false;

  // Newton from `x` at load factor `load`; on success x holds the solution.
  auto newton = [&](Eigen::VectorXd& x, double load, LoadStepReport& report) {
    for (int iteration = 0;; ++iteration) {
      auto t = std::chrono::steady_clock::now();
      problem.evaluate(x, load, residual, &jacobian);
      solution.assembleSeconds += seconds(t);
      const double norm = residual.lpNorm<Eigen::Infinity>();
      report.residuals.push_back(norm);
      if (!std::isfinite(norm)) return Outcome::Diverged;
      // Rounding x alone moves row i of F by about eps (|J| |x|)_i: for slender rods (E A L^2 / E I
      // of 1e6 and more) that floor lies far above any fixed tolerance, and Newton cannot go below it.
      const Eigen::VectorXd floor = (jacobian.cwiseAbs() * x.cwiseAbs()) * (16 * std::numeric_limits<double>::epsilon());
      if ((residual.cwiseAbs() - floor).maxCoeff() <= options.tolerance) return Outcome::Converged;
      if (iteration >= options.maxIterations) return Outcome::Diverged;
      // Growth far beyond the step's starting residual means Newton left the basin of attraction.
      if (iteration >= 3 && norm > 1e3 * std::max(report.residuals.front(), options.tolerance)) return Outcome::Diverged;
      t = std::chrono::steady_clock::now();
      if (!analyzed) {
        lu.analyzePattern(jacobian);
        analyzed = true;
      }
      lu.factorize(jacobian);
      const Eigen::VectorXd dx = lu.info() == Eigen::Success ? Eigen::VectorXd(lu.solve(residual)) : Eigen::VectorXd();
      // Rounding turns an exactly singular stiffness into pivots of 1e-16 and corrections of 1e16:
      // a correction a million times the structure is a mechanism, not a large deformation.
      if (lu.info() != Eigen::Success || !dx.allFinite() || problem.stepNorm(dx) > 1e6)
        throw MechanicsError(problem.source() + ": the stiffness (Jacobian) is singular at load factor " + format(load) +
                             ": the structure is a mechanism; add supports (a single pinned end leaves rotation free) "
                             "or join the loose rods");
      solution.factorizeSeconds += seconds(t);
      ++solution.newtonIterations;
      x -= dx;
      // Newton converges quadratically: after a correction this small, x is accurate to rounding.
      if (problem.stepNorm(dx) < options.tolerance) {
        problem.evaluate(x, load, residual);
        report.residuals.push_back(residual.lpNorm<Eigen::Infinity>());
        return std::isfinite(report.residuals.back()) ? Outcome::Converged : Outcome::Diverged;
      }
    }
  };

  double load = 0.0, step = 1.0 / steps;
  int cuts = 0;
  while (load < 1.0) {
    const double target = std::min(1.0, load + step);
    Eigen::VectorXd x = solution.state;
    LoadStepReport report;
    if (newton(x, target, report) == Outcome::Converged) {
      solution.state = std::move(x);
      load = target;
      report.index = static_cast<int>(solution.steps.size()) + 1;
      report.loadFactor = load;
      report.cuts = cuts;
      if (onStep) onStep(report, solution.state);
      // After a cut, grow the step back towards the planned one when Newton converged easily.
      if (cuts > 0 && report.residuals.size() <= 5) step = std::min(1.0 / steps, 2.0 * step);
      solution.steps.push_back(std::move(report));
      continue;
    }
    if (++cuts > options.maxStepCuts)
      throw ConvergenceError(problem.source() + ": Newton did not converge beyond load factor " + format(load) +
                                 " even with the step cut to " + format(step) +
                                 "; try more load steps (--load-steps), a finer discretization (--refine) or "
                                 "check the loads (a buckling or snap-through point?)",
                             load);
    step *= 0.5;
  }
  solution.totalSeconds = seconds(start);
  return solution;
}

}  // namespace rodfab::mechanics
