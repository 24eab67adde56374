// Newton's method with load stepping and step cutting, tracking the sign of det J along the path
// (critical points, stability) and optionally switching onto a stable branch after a bifurcation.
#include "mechanics/mechanics.hpp"

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

enum class Outcome { Converged, Diverged };

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

// Follows the load path of one problem; one object per solve.
class PathFollower {
public:
  PathFollower(const StaticProblem& problem, const SolverOptions& options)
      : problem_(problem), options_(options), lu_(std::make_shared<JacobianLU>(7)) {}
  Solution run(int steps, const StepCallback& onStep);
  std::optional<Solution> runFrom(const Eigen::VectorXd& start);

private:
  void factorizeReference();
  std::string singularReferenceMessage() const;
  Outcome newton(Eigen::VectorXd& x, double load, LoadStepReport& report);
  bool converged(const Eigen::VectorXd& x) const;
  bool factorize(JacobianLU::Pivoting pivoting = JacobianLU::Pivoting::Reuse);
  Eigen::VectorXd correction();
  void checkCriticalPoint(Eigen::VectorXd& x, double fromLoad, double toLoad);
  Eigen::VectorXd criticalMode(bool transposed) const;
  double loadAlignment(const Eigen::VectorXd& x, double load, const Eigen::VectorXd& psi) const;
  bool switchBranch(Eigen::VectorXd& x, double load);
  bool factorizeAt(const Eigen::VectorXd& x, double load, JacobianLU::Pivoting pivoting = JacobianLU::Pivoting::Reuse);
  void finish();

  // A converged state on the path, with ln |det J| and the relative sign of det J there.
  struct Sample {
    double load = 0.0, logDet = 0.0;
    int sign = 1;
    Eigen::VectorXd state;
  };
  Sample sampleHere(const Eigen::VectorXd& x, double load) const;
  std::optional<Sample> sampleAt(Eigen::VectorXd x, double load, int iterations = 12);
  void lookForDips(const Eigen::VectorXd& x, double load, bool branchSwitched);
  void lookForDipAtEnd();
  void searchDip(Sample lo, Sample best, Sample hi);
  bool narrowDip(Sample& lo, Sample& best, Sample& hi, double width);
  CriticalPoint bisectCrossing(Sample low, Sample high);
  enum class Verdict { Yes, No, Unknown };
  Verdict isDoubleZeroAt(const Sample& best, double width);
  bool branchEndsAfter(const Sample& below, const Sample& best, double width);

  const StaticProblem& problem_;
  const SolverOptions& options_;
  std::shared_ptr<JacobianLU> lu_;
  Eigen::SparseMatrix<double> jacobian_;
  Eigen::VectorXd residual_;
  int referenceSign_ = 0;
  int relativeSign_ = 1;      // sign of det J at the last factorization relative to the reference
  int previousSign_ = 1;      // at the last converged step
  int signChanges_ = 0;       // since the start or the last branch switch, two for each paired crossing
  int pairedCrossings_ = 0;   // critical points with two crossings, since the start or the last branch switch
  std::vector<Sample> recent_;  // the last three converged states (none before the reference is factorized)
  std::vector<double> factorizedValues_;  // of the matrix lu_ holds (jacobian_'s pattern); empty if none
  double residualTolerance_ = 0.0;  // set by factorizeReference, which every solve starts with
  int maxIterations_ = options_.maxIterations;  // Newton's, lower while sampling a dip (sampleAt)
  bool sampledSinceFresh_ = false;  // factorizations near singular matrices since the last with fresh pivots
  Solution solution_;
};

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

// Called after each converged step, x being the new state at `toLoad` and solution_.state the
// previous one: a change of sign of det J between them means a critical point, which is bracketed
// by bisection, classified, and (followStableBranch) left for a stable branch.
void PathFollower::checkCriticalPoint(Eigen::VectorXd& x, double fromLoad, double toLoad) {
  const int before = previousSign_, after = relativeSign_;
  if (before == after) return;
  ++signChanges_;
  CriticalPoint point;
  Eigen::VectorXd nearest = x;  // converged state closest past the critical point
  point.fromLoad = fromLoad, point.toLoad = toLoad;
  Eigen::VectorXd low = solution_.state;
  for (int i = 0; i < 60 && point.toLoad - point.fromLoad > options_.criticalLoadTolerance; ++i) {
    const double middle = 0.5 * (point.fromLoad + point.toLoad);
    Eigen::VectorXd trial = low;
    LoadStepReport scratch;
    if (newton(trial, middle, scratch) != Outcome::Converged || !factorizeAt(trial, middle)) break;
    if (relativeSign_ == before) point.fromLoad = middle, low = std::move(trial);
    else point.toLoad = middle, nearest = std::move(trial);
  }
  if (factorizeAt(nearest, point.toLoad))
    point.loadAlignment = loadAlignment(nearest, point.toLoad, criticalMode(true));
  point.kind = point.loadAlignment < 1e-2 ? CriticalPoint::Kind::Bifurcation : CriticalPoint::Kind::LimitPoint;
  factorizeAt(x, toLoad);
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

PathFollower::Sample PathFollower::sampleHere(const Eigen::VectorXd& x, double load) const {
  return {load, lu_->logAbsDeterminant(), relativeSign_, x};
}

// The equilibrium at `load` by Newton from x, and det J there; none when Newton fails.
std::optional<PathFollower::Sample> PathFollower::sampleAt(Eigen::VectorXd x, double load, int iterations) {
  LoadStepReport scratch;
  // From a nearby equilibrium Newton converges in a few iterations or, past a branch's end, not at all:
  // a dozen tell which (the step's own limit is 30).
  maxIterations_ = std::min(options_.maxIterations, iterations);
  sampledSinceFresh_ = true;
  const bool ok = newton(x, load, scratch) == Outcome::Converged && factorizeAt(x, load);
  maxIterations_ = options_.maxIterations;
  if (!ok) return std::nullopt;
  return sampleHere(x, load);
}

// ln |det J| changes below this are rounding, not a dip (a search takes some thirty Newton solves,
// each of a few iterations from a nearby equilibrium).
constexpr double kLogDetNoise = 1e-6;

// After each converged step (x at `load`, factorized): a step whose |det J| lies below both its
// neighbours', all of one sign, is searched (searchDip) for what det J's sign cannot show: two
// eigenvalues crossing zero together, or a limit point the path jumped past. The first step also
// probes just past the reference: |det J| may dip before it.
void PathFollower::lookForDips(const Eigen::VectorXd& x, double load, bool branchSwitched) {
  if (branchSwitched) recent_.clear();  // another branch: nothing before it is comparable
  recent_.push_back(sampleHere(x, load));
  if (recent_.size() > 3) recent_.erase(recent_.begin());
  if (options_.criticalLoadTolerance >= 1) return;
  const bool oneSign = std::all_of(recent_.begin(), recent_.end(), [&](const Sample& s) { return s.sign == recent_.front().sign; });
  if (!oneSign || recent_.size() < 2) return;
  bool sampled = false;
  if (recent_.size() == 2 && recent_[0].load == 0.0 && recent_[1].logDet > recent_[0].logDet + kLogDetNoise) {
    const Sample& start = recent_[0];
    std::optional<Sample> probe = sampleAt(start.state, std::min(options_.criticalLoadTolerance, 0.5 * load));
    sampled = true;
    if (probe && probe->sign == start.sign && probe->logDet < start.logDet - kLogDetNoise) searchDip(start, std::move(*probe), recent_[1]);
  } else if (recent_.size() == 3 && recent_[1].logDet < std::min(recent_[0].logDet, recent_[2].logDet) - kLogDetNoise) {
    searchDip(recent_[0], recent_[1], recent_[2]);
    sampled = true;
  }
  if (sampled) factorizeAt(x, load, JacobianLU::Pivoting::Fresh);  // the step's own factorization and sign again
}

// At load 1, a |det J| still falling may have passed its bottom within the last step: a probe just
// before the end tells.
void PathFollower::lookForDipAtEnd() {
  if (options_.criticalLoadTolerance >= 1 || recent_.size() < 2) return;
  const Sample& last = recent_.back();
  const Sample& before = recent_[recent_.size() - 2];
  if (last.sign != before.sign || !(last.logDet < before.logDet - kLogDetNoise)) return;
  std::optional<Sample> probe =
      sampleAt(last.state, last.load - std::min(options_.criticalLoadTolerance, 0.5 * (last.load - before.load)));
  if (probe && probe->sign == last.sign && probe->logDet < last.logDet - kLogDetNoise) searchDip(before, std::move(*probe), last);
}

// Narrows the dip bracketed by lo and hi (best below both) by golden-section search to `width`; true
// when a sample between shows the other sign of det J (two single crossings close together), which
// then is best.
bool PathFollower::narrowDip(Sample& lo, Sample& best, Sample& hi, double width) {
  constexpr double kGoldenSection = 0.3819660112501051;  // (3 - sqrt 5) / 2
  for (int i = 0; i < 200 && hi.load - lo.load > width; ++i) {
    const bool right = hi.load - best.load > best.load - lo.load;
    const double t = right ? best.load + kGoldenSection * (hi.load - best.load) : best.load - kGoldenSection * (best.load - lo.load);
    std::optional<Sample> s = sampleAt(best.state, t);
    if (!s) s = Sample{t, std::numeric_limits<double>::infinity(), 0, {}};  // past the branch's end: a bound, sign unknown
    const bool flipped = s->sign != 0 && s->sign != best.sign;
    if (flipped || s->logDet < best.logDet) {
      (right ? lo : hi) = std::move(best);
      best = std::move(*s);
    } else {
      (right ? hi : lo) = std::move(*s);
    }
    if (flipped) return true;
  }
  return false;
}

// The bottom of a dip of |det J| bracketed by lo and hi (best below both). Critical points when a
// sample between shows the other sign (two single crossings, each then bisected), when the branch
// ends just past the bottom (a limit point the path jumped past: snap-through, branchEndsAfter), or
// when |det J| falls as the
// square of the distance to the bottom (isDoubleZeroAt) both at the load tolerance and a hundred
// times closer: a smooth dip flattens out within its core (an arch's near-snap: 2e-4 of the load).
void PathFollower::searchDip(Sample lo, Sample best, Sample hi) {
  const double tolerance = options_.criticalLoadTolerance;
  const Sample outerLo = lo, outerHi = hi;  // equilibria both (steps or probes), whatever bounds replace them
  bool flipped = narrowDip(lo, best, hi, tolerance);
  const double width = std::max(hi.load - lo.load, tolerance);
  CriticalPoint point;
  if (!flipped && branchEndsAfter(lo, best, width)) {
    point.snapThrough = true;
    point.fromLoad = best.load, point.toLoad = best.load + width;
  } else {
    if (!flipped && isDoubleZeroAt(best, width) != Verdict::Yes) return;
    if (!flipped) flipped = narrowDip(lo, best, hi, 1e-2 * tolerance);
    if (flipped) {  // a bound where Newton failed has no state: the equilibrium beyond it brackets instead
      solution_.criticalPoints.push_back(bisectCrossing(lo.state.size() ? lo : outerLo, best));
      solution_.criticalPoints.push_back(bisectCrossing(best, hi.state.size() ? hi : outerHi));
      signChanges_ += 2;
      return;
    }
    // Closer than 1e-5 Newton itself may fail next to a double zero (a slender square column): the
    // law held at the tolerance, and a matrix that singular is no smooth dip's.
    if (isDoubleZeroAt(best, std::max(hi.load - lo.load, 1e-2 * tolerance)) == Verdict::No) return;
    point.fromLoad = lo.load, point.toLoad = hi.load, point.crossings = 2;
    signChanges_ += 2, ++pairedCrossings_;
  }
  if (factorizeAt(best.state, best.load)) point.loadAlignment = loadAlignment(best.state, best.load, criticalMode(true));
  point.kind = point.loadAlignment < 1e-2 && !point.snapThrough ? CriticalPoint::Kind::Bifurcation : CriticalPoint::Kind::LimitPoint;
  solution_.criticalPoints.push_back(point);
}

// One crossing between equilibria `low` and `high` (by load) of opposite signs of det J, bisected to
// the load tolerance (Newton with the step's own iteration limit) and classified as
// checkCriticalPoint does.
CriticalPoint PathFollower::bisectCrossing(Sample low, Sample high) {
  for (int i = 0; i < 60 && high.load - low.load > options_.criticalLoadTolerance; ++i) {
    const double load = 0.5 * (low.load + high.load);
    std::optional<Sample> middle = sampleAt(low.state, load, options_.maxIterations);
    if (!middle) middle = sampleAt(high.state, load, options_.maxIterations);  // from the other side
    if (!middle) break;  // the bracket stays as wide as it is
    (middle->sign == low.sign ? low : high) = std::move(*middle);
  }
  CriticalPoint point;
  point.fromLoad = low.load, point.toLoad = high.load;
  if (factorizeAt(high.state, high.load)) point.loadAlignment = loadAlignment(high.state, high.load, criticalMode(true));
  point.kind = point.loadAlignment < 1e-2 ? CriticalPoint::Kind::Bifurcation : CriticalPoint::Kind::LimitPoint;
  return point;
}

// The branch through `best` ends within `width` above it: Newton (with the step's own iteration limit,
// in one step or two halves) finds no equilibrium there, or one a jump away (below). Under load control a limit point
// cannot be passed on its branch, and a step across it lands on another. An imperfect column's sharp
// but smooth turn needed more than a dozen iterations there, and took them.
bool PathFollower::branchEndsAfter(const Sample& below, const Sample& best, double width) {
  if (best.load + width > 1 || below.state.size() == 0 || !(below.load < best.load)) return false;
  std::optional<Sample> above = sampleAt(best.state, best.load + width, options_.maxIterations);
  if (!above) {
    const std::optional<Sample> half = sampleAt(best.state, best.load + 0.5 * width, options_.maxIterations);
    if (half) above = sampleAt(half->state, best.load + width, options_.maxIterations);
  }
  if (!above) return true;
  // A jump: three times the move below, scaled to `width` linearly or, if more, as the square root
  // (towards a limit point the state runs as the root of the load distance), onto a state where |det J|
  // is ten times larger (the branch's end is a zero of it; the far branch's is not).
  const double movedBelow = problem_.stepNorm(best.state - below.state), spanBelow = best.load - below.load;
  const double allowed = 3 * movedBelow * std::max(width / spanBelow, std::sqrt(width / spanBelow));
  return problem_.stepNorm(above->state - best.state) > allowed + 1e-6 && above->logDet > best.logDet + std::log(10.0);
}

// Near a double zero |det J| grows as the square of the distance: from 4 to 40 bracket widths
// (`width`; the zero lies within one of best) by a factor of 60 to 190 (ln: 4.1 to 5.2) on either
// side. Past a smooth dip's core it does so too; inside it, hardly at all. No if either side says so,
// Unknown when Newton finds no equilibrium at those loads on either side.
PathFollower::Verdict PathFollower::isDoubleZeroAt(const Sample& best, double width) {
  int held = 0;
  for (const double direction : {-1.0, 1.0}) {
    const double nearLoad = best.load + direction * 4 * width, farLoad = best.load + direction * 40 * width;
    if (farLoad < 0 || farLoad > 1) continue;
    const std::optional<Sample> nearer = sampleAt(best.state, nearLoad);
    const std::optional<Sample> farther = nearer ? sampleAt(nearer->state, farLoad) : std::nullopt;
    if (!farther) continue;  // this side tells nothing
    if (farther->logDet - nearer->logDet < 0.75 * 2 * std::log(10.0)) return Verdict::No;
    ++held;
  }
  return held > 0 ? Verdict::Yes : Verdict::Unknown;
}

Solution PathFollower::run(int steps, const StepCallback& onStep) {
  const auto start = std::chrono::steady_clock::now();
  solution_.state = problem_.referenceState();
  factorizeReference();
  recent_ = {sampleHere(solution_.state, 0.0)};
  const double planned = 1.0 / steps;
  double load = 0.0, step = planned;
  int halvings = 0;  // of the planned step, in force
  while (load < 1.0) {
    // Snap to 1 when rounding leaves a sliver (0.1 ten times is 0.9999999999999999).
    double target = load + step;
    if (target > 1.0 - 1e-9 * step) target = 1.0;
    Eigen::VectorXd x = solution_.state;
    LoadStepReport report;
    if (newton(x, target, report) == Outcome::Converged) {
      // det J's sign where the step ended: Newton's last factorization was at an iterate before its last
      // correction (on a nearly linear path the previous step's state), which put critical points one
      // step late. With dead loads the next step's first factorization is this one again (factorize).
      factorizeAt(x, target);
      const std::size_t pointsBefore = solution_.criticalPoints.size();
      checkCriticalPoint(x, load, target);
      previousSign_ = relativeSign_;
      lookForDips(x, target, solution_.criticalPoints.size() > pointsBefore && solution_.criticalPoints.back().branchSwitched);
      solution_.state = std::move(x);
      report.index = static_cast<int>(solution_.steps.size()) + 1;
      report.increment = target - load;
      report.loadFactor = load = target;
      report.cuts = halvings;
      report.determinantSign = relativeSign_;
      if (onStep) onStep(report, solution_.state);
      // After a cut, grow the step back towards the planned one when Newton converged easily.
      if (halvings > 0 && report.residuals.size() <= 5) step = planned / std::ldexp(1.0, --halvings);
      solution_.steps.push_back(std::move(report));
      continue;
    }
    if (++halvings > options_.maxStepCuts)
      throw ConvergenceError(problem_.source() + ": Newton did not converge beyond load factor " + format(load) +
                                 " even with the step cut to " + format(step / 2) +
                                 "; try more load steps (--load-steps), a finer discretization (--spans) or "
                                 "check the loads (a buckling or snap-through point?)",
                             load);
    step = planned / std::ldexp(1.0, halvings);
  }
  lookForDipAtEnd();
  finish();
  solution_.totalSeconds = seconds(start);
  return std::move(solution_);
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

}  // namespace

Solution solveFrom(const StaticProblem& problem, const Eigen::VectorXd& start, const SolverOptions& options,
                   int designLoadSteps) {
  if (start.size() != problem.referenceState().size()) throw std::invalid_argument("solveFrom: a state of the wrong size");
  if (std::optional<Solution> direct = PathFollower(problem, options).runFrom(start)) return std::move(*direct);
  return solve(problem, options, designLoadSteps);
}

Solution solve(const StaticProblem& problem, const SolverOptions& options, int designLoadSteps, const StepCallback& onStep) {
  const int steps = options.loadSteps > 0 ? options.loadSteps : std::max(1, designLoadSteps);
  return PathFollower(problem, options).run(steps, onStep);
}

}  // namespace rodfab::mechanics
