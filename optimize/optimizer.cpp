// The bounded optimizers on log E (or E) scaled to [0, 1] and g scaled by g0: L-BFGS-B (LBFGS++),
// or NLopt's MMA / CCSAQ.
#include "optimize/optimize.hpp"

#include <boost/algorithm/string/join.hpp>
#include <LBFGSB.h>
#include <nlopt.hpp>

#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <stdexcept>
#include <vector>

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
  // A line search that LBFGS++ gave up on and that ended at its lowest trial instead.
  void recordFallback() { ++result_.lineSearchFallbacks; }

private:
  double evaluate(const Eigen::VectorXd& t, Eigen::VectorXd& grad) {
    const Eigen::VectorXd e = modulus(t);
    Evaluation ev = problem_.evaluate(e, true);
    ++result_.evaluations;
    newton_ += ev.newtonIterations;
    if (result_.evaluations == 1) {
      if (!std::isfinite(ev.objective) || !ev.gradient.allFinite()) {
        std::vector<std::string> notFinite;
        for (const CaseObjective& c : ev.cases)
          if (!std::isfinite(c.total())) notFinite.push_back("\"" + c.name + "\"");
        const std::string cases = boost::algorithm::join(notFinite, ", ");
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

// The objective as a line search sees it, keeping the trial with the lowest f.
template <class Objective>
struct TrialRecorder {
  explicit TrialRecorder(Objective& objective) : f(objective) {}
  Objective& f;
  double bestF = std::numeric_limits<double>::infinity();
  Eigen::VectorXd bestX, bestGrad;
  double operator()(const Eigen::VectorXd& x, Eigen::VectorXd& grad) {
    const double value = f(x, grad);
    if (value < bestF) bestF = value, bestX = x, bestGrad = grad;
    return value;
  }
};

// LBFGS++'s More-Thuente line search, then the iteration's report. Debian's LBFGS++ 0.1.0 tests
// its case 2 (the trial lower and still descending: extrapolate) with gt * (fI_lo - step) where
// More and Thuente (and later LBFGS++ versions) have gt * (I_lo - step): once a step past the minimum
// has become the interval's low end, a trial below it that still descends is taken as case 2 and
// extrapolated backwards, to a negative step ("smaller than the minimum value allowed"). On the
// follower box this stopped L-BFGS-B after 5 iterations with an exact gradient and g smooth along
// the search direction (optimize/README.md). When the search throws, the lowest trial is accepted
// if it decreases f sufficiently (Armijo, ftol), as a backtracking search would; L-BFGS-B skips
// the curvature pair when s'y <= 0, so a step without the curvature condition is safe.
template <class Scalar>
class ReportingLineSearch {
public:
  template <class Objective>
  static void LineSearch(Objective& f, Scalar& fx, Eigen::VectorXd& x, Eigen::VectorXd& grad, Scalar& step,
                         const Scalar& stepMax, const Eigen::VectorXd& drt, const Eigen::VectorXd& xp,
                         const LBFGSpp::LBFGSBParam<Scalar>& param) {
    const Scalar fInit = fx, slope = grad.dot(drt);
    TrialRecorder<Objective> trials(f);
    try {
      LBFGSpp::LineSearchMoreThuente<Scalar>::LineSearch(trials, fx, x, grad, step, stepMax, drt, xp, param);
    } catch (const std::runtime_error&) {
      const Scalar bestStep = trials.bestX.size() ? (trials.bestX - xp).dot(drt) / drt.squaredNorm() : Scalar(0);
      if (!(bestStep > 0 && trials.bestF <= fInit + param.ftol * bestStep * slope)) throw;
      x = trials.bestX, fx = trials.bestF, grad = trials.bestGrad, step = bestStep;
      f.recordFallback();
    }
    f.iterationDone(x, fx, grad);
  }
};

// One run of L-BFGS-B from t, at most `iterations`; throws what the objective or LBFGS++ throws.
void runLbfgsB(ScaledObjective& objective, const Settings& settings, int iterations, Eigen::VectorXd& t, double& f) {
  LBFGSpp::LBFGSBParam<double> param;
  param.m = 10;
  param.epsilon = settings.tolerance;
  param.epsilon_rel = 0.0;
  param.max_iterations = iterations;
  param.max_linesearch = 30;
  LBFGSpp::LBFGSBSolver<double, ReportingLineSearch> solver(param);
  const Eigen::VectorXd lower = Eigen::VectorXd::Zero(t.size()), upper = Eigen::VectorXd::Ones(t.size());
  solver.minimize(objective, t, f, lower, upper);
}

// L-BFGS-B from t: the iterations done (the reports after the start). When LBFGS++ gives up on its
// own (a subspace minimization whose direction does not descend, "the moving direction does not
// decrease the objective function value", LBFGS++ issue 15; a line search without a sufficient
// decrease) after a run that took an iteration and lowered g, L-BFGS-B starts again from the best point with an empty
// memory: its first direction is then the projected steepest descent. A run that lowers nothing
// ends the optimization with LBFGS++'s message (rounding stops g from decreasing).
int minimizeLbfgsB(ScaledObjective& objective, const Settings& settings, Eigen::VectorXd& t, double& f, Result& result, int& restarts) {
  for (;;) {
    const double bestBefore = result.final.objective;
    const int done = static_cast<int>(result.history.size()) - 1;
    try {
      runLbfgsB(objective, settings, settings.maxIterations - done, t, f);
      return static_cast<int>(result.history.size()) - 1;
    } catch (const std::exception&) {
      const int now = static_cast<int>(result.history.size()) - 1;
      if (now == done || !(result.final.objective < bestBefore) || now >= settings.maxIterations) throw;
      ++restarts;
      t = objective.scaled(result.modulus).cwiseMax(0.0).cwiseMin(1.0);
    }
  }
}

// NLopt's MMA or CCSAQ from t, every evaluation reported as an iteration, at most maxIterations of
// them; stops where the projected gradient is below the tolerance. Returns the iterations done.
// NLopt's C++ wrapper swallows what an objective throws, so the objective keeps it and stops
// NLopt, and it is thrown again here.
int minimizeNlopt(ScaledObjective& objective, const Settings& settings, const Eigen::VectorXd& t, double f0,
                  const Eigen::VectorXd& grad0, const Result& result) {
  nlopt::opt opt(settings.method == Method::Mma ? nlopt::LD_MMA : nlopt::LD_CCSAQ, static_cast<unsigned>(t.size()));
  opt.set_lower_bounds(0.0);
  opt.set_upper_bounds(1.0);
  opt.set_maxeval(settings.maxIterations + 1);  // NLopt's first evaluation is the start, evaluated already
  std::exception_ptr thrown;
  bool first = true;
  auto f = [&](const std::vector<double>& x, std::vector<double>& grad) {
    try {
      const Eigen::VectorXd tx = Eigen::Map<const Eigen::VectorXd>(x.data(), static_cast<Eigen::Index>(x.size()));
      Eigen::VectorXd g = grad0;
      double value = f0;
      if (!first || tx != t) {
        value = objective(tx, g);
        objective.iterationDone(tx, value, g);
      }
      first = false;
      if (!grad.empty()) Eigen::Map<Eigen::VectorXd>(grad.data(), g.size()) = g;
      if (result.history.back().projectedGradient <= settings.tolerance) opt.force_stop();
      return value;
    } catch (...) {
      thrown = std::current_exception();
      opt.force_stop();
      return 0.0;
    }
  };
  using F = decltype(f);
  opt.set_min_objective([](const std::vector<double>& x, std::vector<double>& grad, void* data) { return (*static_cast<F*>(data))(x, grad); },
                        &f);
  std::vector<double> x(t.data(), t.data() + t.size());
  double value = 0;
  try {
    opt.optimize(x, value);
  } catch (const nlopt::forced_stop&) {
  } catch (const nlopt::roundoff_limited&) {  // rounding stops progress: the best point stands
  }
  if (thrown) std::rethrow_exception(thrown);
  return static_cast<int>(result.history.size()) - 1;
}

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
  double f = 0;
  int restarts = 0;
  Eigen::VectorXd grad(t.size());
  try {
    // The start's report: LBFGS++ evaluates it again and does not report it.
    f = objective(t, grad);
    objective.iterationDone(t, f, grad);
    const bool done = settings.maxIterations == 0 || result.history.back().projectedGradient <= settings.tolerance;
    if (done) result.iterations = 0;
    else if (settings.method == Method::LbfgsB) result.iterations = minimizeLbfgsB(objective, settings, t, f, result, restarts);
    else result.iterations = minimizeNlopt(objective, settings, t, f, grad, result);
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
  if (restarts > 0)
    result.stopReason += " (after " + std::to_string(restarts) + " restart" + (restarts > 1 ? "s" : "") +
                         " of L-BFGS-B from the best point)";
  // The states of the cases belong to the best point.
  if (!objective.lastWasBest()) problem.evaluate(result.modulus, false);
  result.seconds = std::chrono::duration<double>(Clock::now() - begin).count();
  return result;
}

}  // namespace rodfab::optimize
