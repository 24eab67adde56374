// The bounded quasi-Newton loop: L-BFGS-B (LBFGS++) on log E (or E) scaled to [0, 1] and g scaled by g0.
#include "optimize/optimize.hpp"

#include <LBFGSB.h>

#include <chrono>
#include <cmath>
#include <exception>
#include <limits>

namespace rodfab::optimize {

namespace {

using Clock = std::chrono::steady_clock;

// Infinity norm of P(t - grad) - t, P the projection onto [0, 1]^n: zero at a bounded minimum.
double projectedGradientNorm(const Eigen::VectorXd& t, const Eigen::VectorXd& grad) {
  return ((t - grad).cwiseMax(0.0).cwiseMin(1.0) - t).lpNorm<Eigen::Infinity>();
}

struct ObjectiveReached {};
// Carries an exception of ours (a case that diverged, an interrupt) through LBFGS++, whose own
// exceptions (a line search that gives up) are std::exception.
struct Abort {
  std::exception_ptr error;
};

// f(t) = g(E(t)) / g0 (E(t) as Scaling says), with the bookkeeping of the best point and the
// per-iteration report (iterationDone, called by the line search below).
class ScaledObjective {
public:
  ScaledObjective(DesignProblem& problem, const std::function<void(const Iteration&)>& onIteration, Result& result)
      : problem_(problem), onIteration_(onIteration), result_(result), start_(Clock::now()),
        logarithmic_(problem.settings().scaling == Scaling::Logarithmic),
        lower_(logarithmic_ ? std::log(problem.settings().lowerMpa) : problem.settings().lowerMpa),
        span_((logarithmic_ ? std::log(problem.settings().upperMpa) : problem.settings().upperMpa) - lower_),
        lowerMpa_(problem.settings().lowerMpa), upperMpa_(problem.settings().upperMpa) {}

  // t in [0, 1] -> E: linear, or linear in log E (equal steps are equal ratios of E).
  Eigen::VectorXd modulus(const Eigen::VectorXd& t) const {
    const Eigen::ArrayXd x = lower_ + span_ * t.array().min(1.0).max(0.0);
    // Clamped: exp(log E0) is not always E0 to the last bit (exp(log 8) = 8 - 2e-15), and a value
    // below the calibration's floor would be clamped when slicing.
    const Eigen::ArrayXd e = logarithmic_ ? Eigen::ArrayXd(x.exp()) : x;
    return e.max(lowerMpa_).min(upperMpa_).matrix();
  }
  Eigen::VectorXd scaled(const Eigen::VectorXd& e) const {
    const Eigen::ArrayXd x = logarithmic_ ? Eigen::ArrayXd(e.array().log()) : Eigen::ArrayXd(e.array());
    return ((x - lower_) / span_).matrix();
  }

  double operator()(const Eigen::VectorXd& t, Eigen::VectorXd& grad) {
    try {
      return evaluate(t, grad);
    } catch (...) {
      throw Abort{std::current_exception()};
    }
  }

  void iterationDone(const Eigen::VectorXd& t, double f, const Eigen::VectorXd& grad) {
    try {
      report(t, f, grad);
    } catch (const ObjectiveReached&) {
      throw;
    } catch (...) {
      throw Abort{std::current_exception()};
    }
  }

  bool lastWasBest() const { return lastWasBest_; }

private:
  double evaluate(const Eigen::VectorXd& t, Eigen::VectorXd& grad) {
    const Eigen::VectorXd e = modulus(t);
    Evaluation ev = problem_.evaluate(e, true);
    ++result_.evaluations;
    newton_ += ev.newtonIterations;
    if (result_.evaluations == 1) {
      if (!std::isfinite(ev.objective) || !ev.gradient.allFinite()) {
        std::string cases;
        for (const CaseObjective& c : ev.cases)
          if (!std::isfinite(c.total())) cases += (cases.empty() ? "" : ", ") + ("\"" + c.name + "\"");
        throw OptimizeError("the objective at the start is not finite (g = " + std::to_string(ev.objective) + ", load case" +
                            " " + (cases.empty() ? "gradient" : cases) + "): a weight or a target far out of scale");
      }
      g0_ = ev.objective > 0 ? ev.objective : 1.0;
      result_.initial = ev;
    }
    // dE/dt: span, or E span on the logarithmic scale.
    grad = logarithmic_ ? Eigen::VectorXd(ev.gradient.cwiseProduct(e) * (span_ / g0_)) : Eigen::VectorXd(ev.gradient * (span_ / g0_));
    const double f = ev.objective / g0_;
    if (result_.evaluations == 1 || ev.objective < result_.final.objective) {
      result_.final = std::move(ev);
      result_.modulus = e;
    }
    lastWasBest_ = result_.modulus == e;
    return f;
  }

  void report(const Eigen::VectorXd& t, double f, const Eigen::VectorXd& grad) {
    Iteration it;
    it.index = static_cast<int>(result_.history.size());
    it.objective = f * g0_;
    it.relative = f;
    it.projectedGradient = projectedGradientNorm(t, grad);
    it.newtonIterations = newton_;
    it.seconds = std::chrono::duration<double>(Clock::now() - start_).count();
    newton_ = 0;
    result_.history.push_back(it);
    if (onIteration_) onIteration_(it);
    if (it.index > 0 && f <= problem_.settings().objectiveTolerance) throw ObjectiveReached{};
  }

  DesignProblem& problem_;
  const std::function<void(const Iteration&)>& onIteration_;
  Result& result_;
  Clock::time_point start_;
  bool logarithmic_;
  double lower_, span_, lowerMpa_, upperMpa_, g0_ = 1.0;
  int newton_ = 0;
  bool lastWasBest_ = true;
};

// LBFGS++'s More-Thuente line search, then the iteration's report.
template <class Scalar>
class ReportingLineSearch {
public:
  template <class Objective>
  static void LineSearch(Objective& f, Scalar& fx, Eigen::VectorXd& x, Eigen::VectorXd& grad, Scalar& step,
                         const Scalar& stepMax, const Eigen::VectorXd& drt, const Eigen::VectorXd& xp,
                         const LBFGSpp::LBFGSBParam<Scalar>& param) {
    LBFGSpp::LineSearchMoreThuente<Scalar>::LineSearch(f, fx, x, grad, step, stepMax, drt, xp, param);
    f.iterationDone(x, fx, grad);
  }
};

}  // namespace

Result optimize(DesignProblem& problem, const std::function<void(const Iteration&)>& onIteration, Eigen::VectorXd start) {
  const Settings& settings = problem.settings();
  if (start.size() == 0) start = problem.startingModulus();
  if (static_cast<std::size_t>(start.size()) != problem.variableCount())
    throw std::invalid_argument("optimize: a start of " + std::to_string(problem.variableCount()) + " values expected");
  Result result;
  const auto begin = Clock::now();
  ScaledObjective objective(problem, onIteration, result);
  Eigen::VectorXd t = objective.scaled(start).cwiseMax(0.0).cwiseMin(1.0);
  const Eigen::VectorXd lower = Eigen::VectorXd::Zero(t.size()), upper = Eigen::VectorXd::Ones(t.size());

  LBFGSpp::LBFGSBParam<double> param;
  param.m = 10;
  param.epsilon = settings.tolerance;
  param.epsilon_rel = 0.0;
  param.max_iterations = settings.maxIterations;
  param.max_linesearch = 30;
  LBFGSpp::LBFGSBSolver<double, ReportingLineSearch> solver(param);
  double f = 0;
  Eigen::VectorXd grad(t.size());
  try {
    // The start's report: LBFGS++ evaluates it again and does not report it.
    f = objective(t, grad);
    objective.iterationDone(t, f, grad);
    const bool done = settings.maxIterations == 0 || result.history.back().projectedGradient <= settings.tolerance;
    result.iterations = done ? 0 : solver.minimize(objective, t, f, lower, upper);
    result.stopReason = result.iterations >= settings.maxIterations ? "iteration limit" : "converged";
  } catch (const Abort& abort) {
    std::rethrow_exception(abort.error);
  } catch (const ObjectiveReached&) {
    result.iterations = static_cast<int>(result.history.size()) - 1;
    result.stopReason = "objective below tolerance";
  } catch (const std::exception& e) {
    // The line search gives up where rounding stops g from decreasing: the best point stands.
    result.iterations = static_cast<int>(result.history.size()) - 1;
    result.stopReason = std::string("line search: ") + e.what();
  }
  // The states of the cases belong to the best point.
  if (!objective.lastWasBest()) problem.evaluate(result.modulus, false);
  result.seconds = std::chrono::duration<double>(Clock::now() - begin).count();
  return result;
}

}  // namespace rodfab::optimize
