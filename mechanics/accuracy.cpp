// Converged answers: solve, estimate the discretization error by comparison with a solve on half
// the spans (Richardson), and refine by doubling every rod's spans while the estimate is above the
// tolerance.
#include "mechanics/mechanics.hpp"

#include "common/interrupt.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace rodfab::mechanics {

namespace {

// Displacements compared at 4 points per span of the finer discretization. (Displacements, not
// positions: the two bases also represent the drawn centerline a little differently.)
struct Comparison {
  double difference = 0.0;    // mm: largest |(r_a - r_a0)(u) - (r_b - r_b0)(u)|
  double displacement = 0.0;  // mm: largest |r_a(u) - r_a0(u)|
};

Comparison compare(const Design& design, const StaticProblem& a, const Eigen::VectorXd& xa,
                   const StaticProblem& b, const Eigen::VectorXd& xb) {
  Comparison c;
  for (std::size_t r = 0; r < design.rods.size(); ++r) {
    common::throwIfInterrupted();
    const geometry::NurbsCurve& curve = design.rods[r].centerline();
    const int designSpans = static_cast<int>(curve.breakpoints().size()) - 1;
    const int spans = a.discretization().perRod[r] * (a.discretization().degree > 0 ? 1 : designSpans);
    const int samples = 4 * std::max(spans, b.discretization().perRod[r] * (b.discretization().degree > 0 ? 1 : designSpans));
    for (int i = 0; i <= samples; ++i) {
      const double u = curve.domainBegin() + (curve.domainEnd() - curve.domainBegin()) * i / samples;
      const Eigen::Vector3d da = a.position(xa, r, u) - a.position(a.referenceState(), r, u);
      const Eigen::Vector3d db = b.position(xb, r, u) - b.position(b.referenceState(), r, u);
      c.difference = std::max(c.difference, (da - db).norm());
      c.displacement = std::max(c.displacement, da.norm());
    }
  }
  return c;
}

Discretization scaled(const Discretization& d, bool finer) {
  Discretization out = d;
  for (int& spans : out.perRod) spans = finer ? std::min(2 * spans, kMaxSpansPerRod) : std::max(1, (spans + 1) / 2);
  return out;
}

// The finer level's error from the difference between two levels: d / (ratio - 1) for errors
// falling by `ratio` per halving of the spans.
double richardson(double difference, double ratio) { return difference / (ratio - 1.0); }

// The refinement loop of one simulate() call.
class Refiner {
public:
  Refiner(const Design& design, const SolverOptions& solver, int designLoadSteps,
          const AccuracyOptions& accuracy, const LevelCallback& onLevel, Simulation& out)
      : design_(design), solver_(solver), steps_(designLoadSteps), accuracy_(accuracy), onLevel_(onLevel), out_(out),
        order_(out.problem->convergenceOrder()), size_(design.bounds().diagonal().norm()) {}

  // Before any refinement, errors are assumed to fall by 2^(order - 2) per halving of the spans: a
  // quarter of the asymptotic rate, as slender rods reach it late (mechanics/README.md).
  void estimate() {
    const Discretization coarse = scaled(out_.problem->discretization(), false);
    std::unique_ptr<StaticProblem> other;
    Solution o;
    std::string without;  // why the first level is not compared with a coarser one
    if (coarse.perRod == out_.problem->discretization().perRod) without = "every rod has a single span: no coarser discretization";
    else try {
      other = std::make_unique<StaticProblem>(design_, coarse);
      // Spans added past kinks of E(s) on collocation points can make the halved counts the same basis
      // again: compared with itself it would claim no error at all.
      if (other->unknownCount() >= out_.problem->unknownCount()) {
        without = "half the spans make no coarser basis (spans added past kinks of E(s))";
      } else {
        if (onLevel_) onLevel_(Level::Estimate, *other);
        o = solveFrom(*other, other->transferredState(*out_.problem, out_.solution.state), solver_, steps_);
      }
    } catch (const common::Interrupted&) {
      throw;
    } catch (const std::runtime_error& e) {  // ConvergenceError, MechanicsError
      // Half the spans may not carry the load where the first level does (a tightly bent rod under-resolved).
      without = std::string("the solve with half the spans failed (") + e.what() + ")";
    }
    if (!without.empty()) return compareWithFiner(without);
    last_ = compare(design_, *out_.problem, out_.solution.state, *other, o.state);
    fill(aPrioriRatio(), other->unknownCount());
  }

  // Without a coarser level, a solve on twice the spans is compared with the first level instead, and
  // is the answer (one of the refinements); with no refinement allowed, or none possible, no estimate.
  void compareWithFiner(const std::string& why) {
    if (accuracy_.maxRefinements > 0 && refine()) addNote(why + "; the first level was compared with twice the spans instead");
    else out_.estimate.note = why + (out_.estimate.note.empty() ? "" : "; " + out_.estimate.note);
  }

  // Doubles every rod's spans (up to kMaxSpansPerRod) and solves again from the current solution;
  // false if that failed, or if no rod could be refined (a comparison with itself would claim no error).
  bool refine() {
    const Discretization finerSpans = scaled(out_.problem->discretization(), true);
    if (finerSpans.perRod == out_.problem->discretization().perRod) {
      addNote("every rod has the most spans a rod may have (" + std::to_string(kMaxSpansPerRod) + "): not refined further");
      return false;
    }
    const std::vector<int>& now = out_.problem->discretization().perRod;
    std::size_t capped = 0;  // rods the doubling leaves as they are
    for (std::size_t r = 0; r < now.size(); ++r) capped += finerSpans.perRod[r] == now[r];
    if (capped > 0 && out_.estimate.note.find("at the most spans") == std::string::npos)
      addNote(std::to_string(capped) + " rods at the most spans a rod may have are not refined: their error is not in the estimate");
    std::unique_ptr<StaticProblem> finerProblem;
    Solution next;
    try {
      finerProblem = std::make_unique<StaticProblem>(design_, finerSpans);
      if (finerProblem->unknownCount() <= out_.problem->unknownCount()) {
        addNote("twice the spans make no finer basis: not refined further");
        return false;
      }
      if (onLevel_) onLevel_(Level::Refinement, *finerProblem);
      next = solveFrom(*finerProblem, finerProblem->transferredState(*out_.problem, out_.solution.state), solver_, steps_);
    } catch (const common::Interrupted&) {
      throw;
    } catch (const std::runtime_error& e) {
      addNote(std::string("refining further failed: ") + e.what());
      return false;
    }
    const double previous = last_.difference;
    const bool observed = out_.estimate.available;  // a ratio needs two comparisons: the first has the a priori one
    StaticProblem& finer = *finerProblem;
    last_ = compare(design_, finer, next.state, *out_.problem, out_.solution.state);
    out_.estimate.ratio = observed && last_.difference > 0 ? previous / last_.difference : 0.0;
    const std::size_t compared = out_.problem->unknownCount();
    // The path's history (steps, critical points) stays the first level's.
    next.steps = std::move(out_.solution.steps);
    next.criticalPoints = std::move(out_.solution.criticalPoints);
    if (next.stability == Stability::Stable) next.stability = out_.solution.stability;
    next.newtonIterations += out_.solution.newtonIterations;
    next.chordIterations += out_.solution.chordIterations;
    out_.solution = std::move(next);
    *out_.problem = std::move(finer);
    ++out_.refinements;
    // The observed ratio, within what the order allows.
    fill(observed ? std::clamp(out_.estimate.ratio, 2.0, std::ldexp(1.0, order_)) : aPrioriRatio(), compared);
    return true;
  }

  bool needsRefinement() const {
    return out_.estimate.available && out_.estimate.relative > accuracy_.tolerance &&
           out_.refinements < accuracy_.maxRefinements;
  }

private:
  void addNote(const std::string& note) {
    std::string& n = out_.estimate.note;
    n += (n.empty() ? "" : "; ") + note;
  }
  // The ratio assumed before one is observed: see estimate().
  double aPrioriRatio() const { return std::max(2.0, std::ldexp(1.0, order_ - 2)); }
  void fill(double ratio, std::size_t compared) {
    ErrorEstimate& e = out_.estimate;
    e.available = true;
    e.positionError = richardson(last_.difference, ratio);
    e.largestDisplacement = last_.displacement;
    // Relative to the largest displacement, at least a millionth of the structure: Newton stops
    // within about 1e-10 of it, which is all the difference when (almost) nothing moves.
    e.relative = e.positionError / std::max(last_.displacement, 1e-6 * size_);
    e.comparedUnknowns = compared;
  }

  const Design& design_;
  const SolverOptions& solver_;
  int steps_;
  const AccuracyOptions& accuracy_;
  const LevelCallback& onLevel_;
  Simulation& out_;
  int order_;
  double size_;  // bounding-box diagonal of the design, mm
  Comparison last_;  // of the last two levels compared, once the estimate is available
};

}  // namespace

Simulation simulate(const Design& design, Discretization discretization, const SolverOptions& solver,
                    int designLoadSteps, const AccuracyOptions& accuracy, const StepCallback& onStep,
                    const LevelCallback& onLevel) {
  if (!(accuracy.tolerance > 0) || accuracy.tolerance > 1 || accuracy.maxRefinements < 0)
    throw std::invalid_argument("simulate: tolerance in (0, 1] and maxRefinements >= 0 expected");
  const auto start = std::chrono::steady_clock::now();
  discretization.tolerance = accuracy.tolerance;
  Simulation out;
  out.problem = std::make_unique<StaticProblem>(design, discretization);
  if (onLevel) onLevel(Level::Path, *out.problem);
  out.solution = solve(*out.problem, solver, designLoadSteps, onStep);
  if (accuracy.estimate) {
    Refiner refiner(design, solver, designLoadSteps, accuracy, onLevel, out);
    refiner.estimate();
    while (refiner.needsRefinement() && refiner.refine()) {
    }
  }
  out.underResolved = out.problem->leastResolvedRod();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace rodfab::mechanics
