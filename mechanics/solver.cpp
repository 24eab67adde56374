// Newton's method with load stepping and step cutting, tracking the sign of det J along the path
// (critical points, stability) and optionally switching onto a stable branch after a bifurcation.
#include "mechanics/path_follower.hpp"

#include "common/interrupt.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <span>
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

// A fixed start vector for inverse iteration, with no symmetry that could make it orthogonal to
// the mode sought.
Eigen::VectorXd startVector(Eigen::Index n) {
  Eigen::VectorXd v(n);
  for (Eigen::Index i = 0; i < n; ++i) v[i] = 1.0 + 0.5 * std::sin(1.0 + 0.618 * static_cast<double>(i));
  return v.normalized();
}

// The residual a converged state may keep: the tolerance, or 1e-8 of the full load's scaled size
// when the loads are that small (a load of 5e-10 E I / L^2 lay below 1e-10 before any iteration,
// and the reference state passed for its solution: 21 % off, the estimate claiming 3e-11), but not
// below the drawn state's own rounding (without loads it is the solution, and Newton on rounding
// would move it).
// `unloaded` is the residual of the drawn state at load 0.
double residualTolerance(const StaticProblem& problem, const Eigen::VectorXd& unloaded, double tolerance) {
  Eigen::VectorXd loaded;
  problem.evaluate(problem.referenceState(), 1.0, loaded);
  const double load = (loaded - unloaded).lpNorm<Eigen::Infinity>(), rounding = unloaded.lpNorm<Eigen::Infinity>();
  return std::min(tolerance, std::max(1e-8 * load, 4 * rounding));
}

}  // namespace

namespace detail {

bool PathFollower::factorize(JacobianLU::Pivoting pivoting) {
  // The matrix factorized last, asked again (a dead-load structure's J where a step ended, at the next
  // step's load): the factorization stands.
  const std::span<const double> values(jacobian_.valuePtr(), static_cast<std::size_t>(jacobian_.nonZeros()));
  if (pivoting == JacobianLU::Pivoting::Reuse && factorizedValues_.size() == values.size() &&
      std::equal(values.begin(), values.end(), factorizedValues_.begin()))
    return true;
  const auto t = std::chrono::steady_clock::now();
  const bool ok = lu_->factorize(jacobian_, pivoting);
  solution_.factorizeSeconds += seconds(t);
  factorizedValues_.clear();
  if (ok) {
    relativeSign_ = lu_->determinantSign() * referenceSign_;
    factorizedValues_.assign(values.begin(), values.end());
  }
  return ok;
}

bool PathFollower::factorizeAt(const Eigen::VectorXd& x, double load, JacobianLU::Pivoting pivoting) {
  const auto t = std::chrono::steady_clock::now();
  problem_.evaluate(x, load, residual_, &jacobian_);
  solution_.assembleSeconds += seconds(t);
  if (pivoting == JacobianLU::Pivoting::Fresh) sampledSinceFresh_ = false;
  return factorize(pivoting);
}

// The final state's factorization (for adjoints) and sign of det J, exact there rather than at the
// last Newton iterate.
void PathFollower::finish() {
  // After a dip's samples, fresh pivots: reusing those of a nearly singular matrix passes the reuse
  // test too easily, and this factorization serves the adjoints.
  const auto pivoting = sampledSinceFresh_ ? JacobianLU::Pivoting::Fresh : JacobianLU::Pivoting::Reuse;
  if (!factorizeAt(solution_.state, 1.0, pivoting))
    throw ConvergenceError(problem_.source() + ": the Jacobian is singular at the converged state of load factor 1: the "
                           "structure is exactly at a critical (buckling) point; change the load slightly", 1.0);
  if (!solution_.steps.empty()) solution_.steps.back().determinantSign = relativeSign_;
  // From the stable reference the first critical point passed always leaves it unstable: one crossing
  // flips det J's sign, two together (a paired crossing) do not but leave two modes unstable.
  if (relativeSign_ < 0 || (signChanges_ == 2 && pairedCrossings_ == 1)) solution_.stability = Stability::Unstable;
  else solution_.stability = signChanges_ == 0 ? Stability::Stable : Stability::Undetermined;
  solution_.tangent = lu_;
  solution_.factorizations = lu_->factorizations();
  solution_.refactorizations = lu_->refactorizations();
}

// Why the reference Jacobian is singular: a mechanism, or (as often) a rod so slender that its
// stiffness matrix is singular to double precision, which no support cures.
std::string PathFollower::singularReferenceMessage() const {
  std::string message = problem_.source() + ": the stiffness (Jacobian) of the undeformed structure is singular to working precision: "
                        "either the structure is a mechanism (add supports: a single pinned end leaves rotation free; or join the "
                        "loose rods)";
  const auto [rod, ratio] = problem_.mostSlenderRod();
  if (ratio >= 1e3) {
    message += ", or its rods are too slender for double precision: " + rod + " is " + format(ratio) +
               " times longer than thick (above about 1e4 the bending and stretching stiffnesses lie 1e8 apart); "
               "split it, thicken it or shorten it";
  }
  return message;
}

// The reference state's Jacobian: its determinant's sign is the stable one (the drawn design is
// stress-free), and a singular one means the supports leave a rigid-body motion free. Rounding may
// turn an exactly singular matrix into tiny pivots instead of a zero one, so solving J v = J 1 must
// also give back v = 1.
void PathFollower::factorizeReference() {
  common::throwIfInterrupted();
  const Eigen::VectorXd& x0 = problem_.referenceState();
  problem_.evaluate(x0, 0.0, residual_, &jacobian_);
  residualTolerance_ = residualTolerance(problem_, residual_, options_.tolerance);
  referenceSign_ = 1;
  bool regular = factorize();
  if (regular) {
    const Eigen::VectorXd ones = Eigen::VectorXd::Ones(x0.size());
    const Eigen::VectorXd back = lu_->solve(jacobian_ * ones);
    regular = back.allFinite() && (back - ones).lpNorm<Eigen::Infinity>() < 1e-4;
  }
  if (!regular) throw MechanicsError(singularReferenceMessage());
  referenceSign_ = lu_->determinantSign();
  relativeSign_ = 1;
}

// Newton from `x` at load factor `load`; on success x holds the solution. Once a correction is
// small (the quadratic phase), further corrections reuse the last factorization (chord steps) as
// long as each cuts the residual tenfold; otherwise, and from any failure, it is full Newton again.
Outcome PathFollower::newton(Eigen::VectorXd& x, double load, LoadStepReport& report) {
  bool chord = false;          // the next correction reuses the last factorization
  Eigen::VectorXd beforeChord;  // the state before the last chord step, empty if the last was full
  for (int iteration = 0;; ++iteration) {
    common::throwIfInterrupted();  // an iteration of a large structure takes up to a few tenths of a second
    const auto t = std::chrono::steady_clock::now();
    problem_.evaluate(x, load, residual_);
    solution_.assembleSeconds += seconds(t);
    const double norm = residual_.lpNorm<Eigen::Infinity>();
    if (beforeChord.size() > 0 && !(norm < 0.1 * report.residuals.back())) {  // the chord step contracted too little
      chord = false;
      if (!(norm < report.residuals.back())) {  // nor helped at all: undo it
        x = beforeChord;
        problem_.evaluate(x, load, residual_);
      }
    }
    beforeChord.resize(0);
    report.residuals.push_back(residual_.lpNorm<Eigen::Infinity>());
    if (!std::isfinite(report.residuals.back())) return Outcome::Diverged;
    // Before any correction only a residual within the tolerance itself counts: the rounding floor
    // converged() allows can exceed a tiny load's whole residual, and the start is then no solution.
    if (iteration == 0 ? report.residuals.back() <= residualTolerance_ : converged(x)) return Outcome::Converged;
    if (iteration >= maxIterations_) return Outcome::Diverged;
    // Growth far beyond the step's starting residual means Newton left the basin of attraction.
    if (iteration >= 3 && report.residuals.back() > 1e3 * std::max(report.residuals.front(), options_.tolerance))
      return Outcome::Diverged;
    Eigen::VectorXd dx;
    if (chord) {
      beforeChord = x;
      dx = lu_->solve(residual_);
      ++solution_.chordIterations, ++report.chordIterations;
    } else {
      if (!factorizeAt(x, load)) return Outcome::Diverged;  // singular on the way: cut the step
      dx = correction();
      ++solution_.newtonIterations;
    }
    // A correction a million times the structure comes from a (nearly) singular Jacobian.
    if (!dx.allFinite() || problem_.stepNorm(dx) > 1e6) return Outcome::Diverged;
    x -= dx;
    const double step = problem_.stepNorm(dx);
    // Newton converges quadratically: after a correction this small, x is accurate to rounding.
    if (step < options_.tolerance) {
      problem_.evaluate(x, load, residual_);
      report.residuals.push_back(residual_.lpNorm<Eigen::Infinity>());
      return std::isfinite(report.residuals.back()) ? Outcome::Converged : Outcome::Diverged;
    }
    // Not from the first iteration: its Jacobian is the previous state's, and the last
    // factorization should stay close to the solution (its determinant's sign is used).
    chord = chord || (options_.chordSteps && iteration >= 1 && step < 1e-3);
  }
}

// Converged when every row of the residual is within the tolerance of its rounding floor: rounding
// x alone moves row i of F by about eps (|J| |x|)_i, which for slender rods (E A L^2 / E I of 1e6
// and more) lies far above any fixed tolerance. J is the last one assembled, close enough for this.
bool PathFollower::converged(const Eigen::VectorXd& x) const {
  if (jacobian_.rows() != x.size()) return residual_.lpNorm<Eigen::Infinity>() <= residualTolerance_;
  const Eigen::VectorXd floor = (jacobian_.cwiseAbs() * x.cwiseAbs()) * (16 * std::numeric_limits<double>::epsilon());
  return (residual_.cwiseAbs() - floor).maxCoeff() <= residualTolerance_;
}

// The Newton correction J^-1 F. With reused pivots the solve is checked: its backward error
// |J dx - F| / (|J| |dx| + |F|) (largest entries) must be near rounding, else the pivots are renewed.
Eigen::VectorXd PathFollower::correction() {
  const auto t = std::chrono::steady_clock::now();
  Eigen::VectorXd dx = lu_->solve(residual_);
  if (lu_->pivotsReused() && dx.allFinite()) {
    const double error = (jacobian_ * dx - residual_).lpNorm<Eigen::Infinity>();
    const double scale = (jacobian_.cwiseAbs() * dx.cwiseAbs() + residual_.cwiseAbs()).lpNorm<Eigen::Infinity>();
    if (!(error <= 1e-11 * scale)) {
      ++solution_.pivotRenewals;
      dx = factorize(JacobianLU::Pivoting::Fresh) ? lu_->solve(residual_) : Eigen::VectorXd();
    }
  }
  solution_.factorizeSeconds += seconds(t);
  return dx;
}

// The eigenvector of J (or of J^T) with the eigenvalue nearest 0, by inverse iteration with the
// last factorization; just past a critical point that eigenvalue is far smaller than the next.
Eigen::VectorXd PathFollower::criticalMode(bool transposed) const {
  Eigen::VectorXd v = startVector(jacobian_.rows());
  for (int i = 0; i < 12; ++i) {
    v = transposed ? lu_->solveTransposed(v) : lu_->solve(v);
    if (!v.allFinite() || v.norm() == 0) break;
    v.normalize();
  }
  return v;
}

double PathFollower::loadAlignment(const Eigen::VectorXd& x, double load, const Eigen::VectorXd& psi) const {
  const double h = 1e-4;
  Eigen::VectorXd up, down;
  problem_.evaluate(x, load + h, up);
  problem_.evaluate(x, load - h, down);
  const Eigen::VectorXd dF = (up - down) / (2 * h);
  const double scale = psi.norm() * dF.norm();
  return scale > 0 && std::isfinite(scale) ? std::abs(psi.dot(dF)) / scale : 0.0;
}

// The point's load alignment, from the critical left eigenvector at (x, load), and its kind: a
// bifurcation when the load does not drive the mode (below 1e-2), else (and always for a
// snap-through) a limit point.
void PathFollower::classify(CriticalPoint& point, const Eigen::VectorXd& x, double load) {
  if (factorizeAt(x, load)) point.loadAlignment = loadAlignment(x, load, criticalMode(true));
  point.kind = point.loadAlignment < 1e-2 && !point.snapThrough ? CriticalPoint::Kind::Bifurcation : CriticalPoint::Kind::LimitPoint;
}

// One crossing between equilibria `low` and `high` (by load) of opposite signs of det J, bisected to
// the load tolerance (Newton with the step's own iteration limit, from the side below or, where it
// fails there, from the side above) and classified at the equilibrium nearest past it. With `mayJump`
// (the two ends of a load step), when the bracket's two sides lie on different branches it is a limit
// point the path jumped past (the branch through `low` ends inside it), classified at that end: a
// clamped arch's snap passed as a "bifurcation" with the snapped state's mode (jumpedAcross).
CriticalPoint PathFollower::bisectCrossing(Sample low, Sample high, bool mayJump) {
  const Sample outerLow = low, outerHigh = high;
  for (int i = 0; i < 60 && high.load - low.load > options_.criticalLoadTolerance; ++i) {
    const double load = 0.5 * (low.load + high.load);
    std::optional<Sample> middle = sampleAt(low.state, load, options_.maxIterations);
    if (!middle) middle = sampleAt(high.state, load, options_.maxIterations);  // from the other side
    if (!middle) break;  // the bracket stays as wide as it is
    (middle->sign == low.sign ? low : high) = std::move(*middle);
  }
  CriticalPoint point;
  point.fromLoad = low.load, point.toLoad = high.load;
  point.snapThrough = mayJump && jumpedAcross(outerLow, outerHigh, low, high);
  const Sample& at = point.snapThrough ? low : high;
  classify(point, at.state, at.load);
  return point;
}

// Whether the narrowed bracket [low, high] of [outerLow, outerHigh] spans a jump between branches: the
// state across it moved more than three times the whole step's move scaled to its width as the
// square root (towards a limit point a branch's state runs as the root of the load distance; across a
// crossing on one branch it moves as the width), onto a state where |det J| is ten times larger (the
// branch's end is a zero of it; the far branch's is not), as branchEndsAfter asks. A bracket not
// narrowed at least fourfold tells nothing.
bool PathFollower::jumpedAcross(const Sample& outerLow, const Sample& outerHigh, const Sample& low, const Sample& high) const {
  const double outerWidth = outerHigh.load - outerLow.load, width = high.load - low.load;
  if (!(width < 0.25 * outerWidth) || low.state.size() == 0 || high.state.size() == 0) return false;
  const double outerMove = problem_.stepNorm(outerHigh.state - outerLow.state);
  return problem_.stepNorm(high.state - low.state) > 3 * outerMove * std::sqrt(width / outerWidth) + 1e-6 &&
         high.logDet > low.logDet + std::log(10.0);
}

// Called after each converged step, x being the new state at `toLoad` and solution_.state the
// previous one: a change of sign of det J between them means a critical point, which is bracketed
// by bisection, classified, and (followStableBranch) left for a stable branch.
void PathFollower::checkCriticalPoint(Eigen::VectorXd& x, double fromLoad, double toLoad) {
  const int before = previousSign_, after = relativeSign_;
  if (before == after) return;
  ++signChanges_;
  const double lowLogDet = recent_.empty() ? 0.0 : recent_.back().logDet;  // solution_.state's (lookForDips)
  CriticalPoint point = bisectCrossing({fromLoad, lowLogDet, before, solution_.state}, {toLoad, lu_->logAbsDeterminant(), after, x}, true);
  factorizeAt(x, toLoad);
  if (point.snapThrough) signChanges_ = pairedCrossings_ = 0;  // another branch: its sign alone tells, as after a switch
  if (options_.followStableBranch && point.kind == CriticalPoint::Kind::Bifurcation && after < 0 &&
      switchBranch(x, toLoad)) {
    point.branchSwitched = true;
    signChanges_ = pairedCrossings_ = 0;
  }
  solution_.criticalPoints.push_back(point);
}

// From the unstable state x at `load`, pushes along the critical mode (both ways, growing) until
// Newton lands on an equilibrium with the reference sign of det J: the stable branch.
bool PathFollower::switchBranch(Eigen::VectorXd& x, double load) {
  Eigen::VectorXd mode = criticalMode(false);
  mode /= std::max(problem_.stepNorm(mode), 1e-300);  // largest entry: 1 structure size or 1 in q
  for (double amplitude : {0.01, 0.03, 0.1, 0.3})
    for (double direction : {1.0, -1.0}) {
      Eigen::VectorXd trial = x + direction * amplitude * mode;
      LoadStepReport scratch;
      if (newton(trial, load, scratch) == Outcome::Converged && factorizeAt(trial, load) && relativeSign_ > 0) {
        x = std::move(trial);
        return true;
      }
    }
  return false;
}

Solution PathFollower::run(int steps, const StepCallback& onStep) {
  const auto start = std::chrono::steady_clock::now();
  solution_.state = problem_.referenceState();
  factorizeReference();
  recent_ = {sampleHere(solution_.state, 0.0)};
  uncutState_ = solution_.state, uncutLogDet_ = recent_.back().logDet;
  const double planned = 1.0 / steps;
  double load = 0.0, step = planned;
  int halvings = 0;  // of the planned step, in force
  while (load < 1.0) {
    // Snap to 1 when rounding leaves a sliver (0.1 ten times is 0.9999999999999999).
    double target = load + step;
    if (target > 1.0 - 1e-9 * step) target = 1.0;
    Eigen::VectorXd x = solution_.state;
    LoadStepReport report;
    const bool converged = newton(x, target, report) == Outcome::Converged;
    const std::size_t pointsBefore = solution_.criticalPoints.size();
    if (!converged && ++halvings <= options_.maxStepCuts) {
      step = planned / std::ldexp(1.0, halvings);
      continue;
    }
    // The branch ends within the smallest step: under load control the structure snaps onto another
    // branch there, which coarser steps had jumped onto (a clamped arch: 3 to 40 steps snapped, 60 or
    // more stopped at the limit point with an error).
    if (!converged && !jumpPastBranchEnd(x, load, step, planned, target, report))
      throw ConvergenceError(problem_.source() + ": Newton did not converge beyond load factor " + format(load) +
                                 " even with the step cut to " + format(step) +
                                 "; try more load steps (--load-steps), a finer discretization (--spans) or "
                                 "check the loads (a buckling or snap-through point?)",
                             load);
    // det J's sign where the step ended: Newton's last factorization was at an iterate before its last
    // correction (on a nearly linear path the previous step's state), which put critical points one
    // step late. With dead loads the next step's first factorization is this one again (factorize).
    factorizeAt(x, target);
    if (converged) checkCriticalPoint(x, load, target);
    previousSign_ = relativeSign_;
    const bool otherBranch = solution_.criticalPoints.size() > pointsBefore &&
                             (solution_.criticalPoints.back().branchSwitched || solution_.criticalPoints.back().snapThrough);
    lookForDips(x, target, otherBranch);
    solution_.state = std::move(x);
    report.index = static_cast<int>(solution_.steps.size()) + 1;
    report.increment = target - load;
    report.loadFactor = load = target;
    report.cuts = halvings;
    report.determinantSign = relativeSign_;
    if (onStep) onStep(report, solution_.state);
    // After a cut, grow the step back towards the planned one when Newton converged easily.
    if (!converged) halvings = 0, step = planned;
    else if (halvings > 0 && report.residuals.size() <= 5) step = planned / std::ldexp(1.0, --halvings);
    if (halvings == 0 || otherBranch) uncutState_ = solution_.state, uncutLogDet_ = recent_.back().logDet;
    solution_.steps.push_back(std::move(report));
  }
  lookForDipAtEnd();
  finish();
  solution_.totalSeconds = seconds(start);
  return std::move(solution_);
}

// Where Newton finds no equilibrium from the last one (solution_.state at `load`) even `smallest` on:
// steps from a sixteenth of the planned one, doubling up to load 1, until Newton lands on one (x, at
// `target`, its `report`). Recorded as a snap-through between `load` and `load + smallest`, classified at the
// branch's end, the path continuing on the new branch (its sign of det J alone tells). False when
// none is found.
bool PathFollower::jumpPastBranchEnd(Eigen::VectorXd& x, double load, double smallest, double planned, double& target,
                                     LoadStepReport& report) {
  // A branch's end is a zero of det J: |det J| must have fallen tenfold since the cuts began (at the
  // arch's limit, 2^-16 of a step away, it had fallen 250-fold), else Newton failed for another reason.
  if (recent_.empty() || !(recent_.back().logDet < uncutLogDet_ - std::log(10.0))) return false;
  // From the branch's end J is nearly singular and Newton's first correction flies off: the state
  // where the steps began to be cut is tried too (a clamped arch jumped from there).
  // Increments from a sixteenth of the planned step up, doubling (a limit at 0.92 of the load with
  // 0.1 steps: the only planned target, 1, was out of Newton's reach; 0.93 was not).
  const auto lands = [&] {
    for (const Eigen::VectorXd* from : {&solution_.state, &uncutState_})
      for (double increment = std::max(planned / 16, 16 * smallest); from->size() > 0; increment *= 2) {
        target = std::min(1.0, load + increment);
        x = *from;
        report = LoadStepReport{};
        if (newton(x, target, report) == Outcome::Converged) return true;
        if (target >= 1.0) break;
      }
    return false;
  };
  // Else from the branch's end pushed along its critical mode (the way the structure snaps), a few
  // amplitudes each way, as switchBranch pushes (a clamped arch at 0.92 of its load in 10 steps).
  const auto landsPushed = [&] {
    if (!factorizeAt(solution_.state, load)) return false;
    Eigen::VectorXd mode = criticalMode(false);
    mode /= std::max(problem_.stepNorm(mode), 1e-300);
    for (double amplitude : {0.03, 0.1})
      for (double direction : {1.0, -1.0})
        for (double increment : {planned / 4, planned}) {
          target = std::min(1.0, load + increment);
          x = solution_.state + direction * amplitude * mode;
          report = LoadStepReport{};
          if (newton(x, target, report) == Outcome::Converged) return true;
        }
    return false;
  };
  if (!lands() && !landsPushed()) return false;
  CriticalPoint point;
  point.fromLoad = load, point.toLoad = load + smallest, point.snapThrough = true;
  classify(point, solution_.state, load);
  solution_.criticalPoints.push_back(point);
  signChanges_ = pairedCrossings_ = 0;
  return true;
}

// Newton at load 1 straight from `start`; none if it does not converge.
std::optional<Solution> PathFollower::runFrom(const Eigen::VectorXd& start) {
  const auto begin = std::chrono::steady_clock::now();
  factorizeReference();
  Eigen::VectorXd x = start;
  LoadStepReport report;
  if (newton(x, 1.0, report) != Outcome::Converged) return std::nullopt;
  solution_.state = std::move(x);
  report.index = 1;
  report.loadFactor = report.increment = 1.0;
  solution_.steps.push_back(std::move(report));
  finish();
  solution_.totalSeconds = seconds(begin);
  return std::move(solution_);
}

}  // namespace detail

Solution solveFrom(const StaticProblem& problem, const Eigen::VectorXd& start, const SolverOptions& options,
                   int designLoadSteps) {
  if (start.size() != problem.referenceState().size()) throw std::invalid_argument("solveFrom: a state of the wrong size");
  if (std::optional<Solution> direct = detail::PathFollower(problem, options).runFrom(start)) return std::move(*direct);
  return solve(problem, options, designLoadSteps);
}

Solution solve(const StaticProblem& problem, const SolverOptions& options, int designLoadSteps, const StepCallback& onStep) {
  const int steps = options.loadSteps > 0 ? options.loadSteps : std::max(1, designLoadSteps);
  return detail::PathFollower(problem, options).run(steps, onStep);
}

}  // namespace rodfab::mechanics
