// The critical points det J's sign cannot show, from dips of |det J| along the load path
// (mechanics/README.md, "What the sign cannot show"): two eigenvalues crossing together, two single
// crossings within one step, a limit point the path jumped past.
#include "mechanics/path_follower.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace rodfab::mechanics::detail {

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
void PathFollower::lookForDips(const Eigen::VectorXd& x, double load, bool otherBranch) {
  if (otherBranch) recent_.clear();  // switched or jumped onto another branch: nothing before it is comparable
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
    signChanges_ = pairedCrossings_ = 0;  // the path is on another branch: its sign alone tells, as at the other snaps
  } else {
    if (!flipped && isDoubleZeroAt(best, width) != Verdict::Yes) return;
    if (!flipped) flipped = narrowDip(lo, best, hi, 1e-2 * tolerance);
    if (flipped) {  // a bound where Newton failed has no state: the equilibrium beyond it brackets instead
      // The samples of a dip are taken from its lowest equilibrium, whichever branch that lies on: a
      // jump across a bracket here tells no snap apart from Newton's noise next to a double zero (a 400
      // mm column of 1 x 0.9999965 mm in two steps read as one), so neither crossing is taken for one.
      solution_.criticalPoints.push_back(bisectCrossing(lo.state.size() ? lo : outerLo, best, false));
      solution_.criticalPoints.push_back(bisectCrossing(best, hi.state.size() ? hi : outerHi, false));
      signChanges_ += 2;
      return;
    }
    // Closer than 1e-5 Newton itself may fail next to a double zero (a slender square column): the
    // law held at the tolerance, and a matrix that singular is no smooth dip's.
    if (isDoubleZeroAt(best, std::max(hi.load - lo.load, 1e-2 * tolerance)) == Verdict::No) return;
    point.fromLoad = lo.load, point.toLoad = hi.load, point.crossings = 2;
    signChanges_ += 2, ++pairedCrossings_;
  }
  classify(point, best.state, best.load);
  solution_.criticalPoints.push_back(point);
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

}  // namespace rodfab::mechanics::detail
