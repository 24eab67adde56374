// Static equilibrium of rod structures: geometrically exact Cosserat rods discretized by
// isogeometric collocation (centerline r and quaternion q on each rod's NURBS basis, collocated at
// the Greville abscissae), rigid joints between rod ends, Newton's method with load stepping.
//
// Units follow the design file: mm, MPa, N, N mm. Loads and prescribed displacements and rotations
// grow linearly with the load factor from 0 (the design as drawn, stress-free) to 1.
//
// Interrupts: building a StaticProblem (per rod), every Newton iteration and the error estimate's
// comparison (per rod) poll common::throwIfInterrupted(), so solve(), solveFrom() and simulate()
// throw common::Interrupted within a few tenths of a second of SIGINT / SIGTERM, whatever they
// would otherwise throw; nothing they return is then made.
#pragma once

#include "geometry/rod.hpp"
#include "mechanics/mechanics_file.hpp"
#include "mechanics/mechanics_spec.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::mechanics {

namespace detail {
struct DiscreteStructure;
}

// A design that cannot be simulated (no supports, an unresolvable load point, a centerline the
// collocation cannot use...). what() reads `FILE: JSON.PATH: what is wrong and what was expected`.
class MechanicsError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

// Newton did not converge even with the load step cut to 1 / 2^maxStepCuts of the planned one.
class ConvergenceError : public std::runtime_error {
public:
  ConvergenceError(const std::string& message, double lastConvergedLoad)
      : std::runtime_error(message), lastConvergedLoad_(lastConvergedLoad) {}
  double lastConvergedLoad() const { return lastConvergedLoad_; }

private:
  double lastConvergedLoad_;
};

// Spans per rod are limited to this many, and a problem to this many unknowns.
constexpr int kMaxSpansPerRod = 4096;
constexpr std::size_t kMaxUnknowns = 2'000'000;

// How each rod's centerline becomes the solver's basis.
struct Discretization {
  // 0 keeps each centerline's degree and NURBS basis, refined exactly by knot insertion. Another
  // degree rebuilds each rod as a B-spline of that degree, interpolating the design's centerline at
  // the new collocation points (geometric error of order h^(degree+1)), its knots uniform between
  // the kinks of the rod's modulus field and the knots where the drawn centerline is only C1, where
  // they are repeated degree - 1 times.
  // Even degrees converge at order p, odd ones at p - 1; primal collocation locks in slender and
  // curved rods less the higher the order, hence 6 (mechanics/README.md).
  int degree = 6;
  // Rebuilt rods: spans per rod; 0 chooses each rod's own from its slenderness, drawn turning,
  // design spans and modulus field (automatic, aiming at `tolerance`).
  int spans = 0;
  // Design basis (degree 0): knots inserted per design span; -1 chooses the least that reaches the
  // automatic span count, and refuses (MechanicsError) a rod whose degree would need more than 256.
  int refine = -1;
  // Relative accuracy of positions the automatic span counts aim at.
  double tolerance = 1e-4;
  // Per rod, in design order, overriding the above: rebuilt rods' spans, or on the design basis the
  // solver spans per design span (refine + 1). Rods beyond its size use the rules above.
  std::vector<int> perRod;
};

// Heap memory of a problem and of solving it, in bytes (StaticProblem::memoryEstimate).
struct SolveMemory {
  std::uint64_t problem = 0;  // the StaticProblem itself: rods, nodes, layouts, the Jacobian's pattern (counted)
  // One solve's peak beyond the problem (solve, solveFrom): the Jacobian, JacobianLU's copies of it,
  // KLU's factors from its symbolic analysis with room for pivoting, Newton's vectors, the
  // assembly's scratch (estimated).
  std::uint64_t solve = 0;
  std::uint64_t kept = 0;  // what a Solution keeps once solved: its state and factorization (`tangent`)
};

// The discrete nonlinear system F(x, load) = 0. x holds, rod after rod, each control point's
// position (3) and quaternion (4); there are as many equations as unknowns: 7 per collocation
// point (force and moment balance, unit quaternion), with the rows of each rod's two end points
// replaced by the joint, support and end-load conditions of the node the end belongs to. Where a
// joint (a T-joint), load or support acts inside a rod, its solver basis has a C0 knot (multiplicity
// = degree) whose control point carries that node's rows: there n and m jump by the point force and
// moment (mechanics/README.md, "T-joints and interior places").
// Const members may be called from several threads at once.
// A rod with fewer spans than its degree needs for even 1 % accuracy (StaticProblem::leastResolvedRod).
struct UnderResolvedRod {
  std::string rod;         // `rods[i] "NAME"`
  int degree = 0;          // of its solver basis
  int spans = 0;           // of its solver basis, over the whole rod
  double needed = 0;       // spans the a priori model asks for `relative` (may exceed kMaxSpansPerRod)
  double relative = 1e-2;  // the accuracy that count is for: 1e-2, or the discretization's tolerance if looser
};

class StaticProblem {
public:
  // Throws MechanicsError, or std::invalid_argument for an out-of-range Discretization.
  explicit StaticProblem(const Design& structure, const Discretization& discretization = {});
  ~StaticProblem();
  StaticProblem(StaticProblem&&) noexcept;
  StaticProblem& operator=(StaticProblem&&) noexcept;

  std::size_t unknownCount() const;
  std::size_t rodCount() const;
  std::size_t jointCount() const;    // nodes where two or more rod ends meet
  std::size_t supportCount() const;
  const std::string& source() const;
  // The discretization as resolved: perRod holds every rod's spans (rebuilt) or spans per design
  // span (design basis), so it reproduces this problem, and halving or doubling them coarsens or
  // refines it.
  const Discretization& discretization() const;
  // Lowest collocation convergence order among the rods (degree p: p if even, p - 1 if odd).
  int convergenceOrder() const;
  // The rod of largest length over thickness (its section's smaller dimension), as `rods[i] "NAME"`,
  // and that ratio: past about 1e4 its stiffness is singular to double precision (E A L^2 / E I over 1e8).
  std::pair<std::string, double> mostSlenderRod() const;
  // The rod whose solver basis falls furthest short of the spans the a priori model
  // (mechanics/README.md, "Automatic spans") asks at its degree for a relative accuracy of 1e-2 (or the
  // discretization's tolerance, if looser); none if every rod has them. Below them collocation of slender rods still locks: answers can be far off (bent
  // the wrong way, critical points where there are none) and the error estimate far too small. The
  // automatic span counts aim at 1e-4, so only counts given by hand (--spans, --refine) fall short.
  std::optional<UnderResolvedRod> leastResolvedRod() const;
  // What det J cannot see in this structure (mechanics/README.md, "Stability"), none if nothing:
  // follower loads (not conservative: neither det J's sign nor its dips decide stability).
  std::optional<std::string> stabilityBlindSpot() const;

  // The undeformed configuration (a solution at load 0).
  const Eigen::VectorXd& referenceState() const;

  // Scaled residual (dimensionless: forces by E I / L^2 and moments by E I / L of their rod,
  // positions by the rod length) and, when `jacobian` is given, its exact derivative (given the
  // problem's sparsity pattern unless it has it already). Parallel over collocation points (TBB);
  // the result does not depend on the thread count. std::invalid_argument for x of the wrong size.
  void evaluate(const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                Eigen::SparseMatrix<double>* jacobian = nullptr) const;

  // Centerline point (mm) and rotation of rod `rod` at parameter u (the design's, clamped to its
  // domain) in state x. std::out_of_range for a rod index from rodCount() on, std::invalid_argument
  // for x of the wrong size.
  Eigen::Vector3d position(const Eigen::VectorXd& x, std::size_t rod, double u) const;
  Eigen::Matrix3d rotation(const Eigen::VectorXd& x, std::size_t rod, double u) const;
  // A state of this discretization interpolating state x of `from`, another discretization of the
  // same design, at this one's collocation points (positions and quaternions); a good Newton start.
  // std::invalid_argument if `from` discretizes a different structure.
  Eigen::VectorXd transferredState(const StaticProblem& from, const Eigen::VectorXd& x) const;
  // Largest change of x in units of the structure: positions / its size, quaternions as they are.
  // std::invalid_argument for dx of the wrong size.
  double stepNorm(const Eigen::VectorXd& dx) const;

  // The structure in state x as a design: the (refined) centerlines with the solved control points
  // and an `orientation` quaternion spline per rod; sections, caps and moduli as in the input; the
  // input's mechanics block with places given by point turned into rod name and end, or rod name
  // and parameter (the points have moved), so the result can be simulated again. std::invalid_argument for x of the wrong
  // size; std::invalid_argument from geometry::Rod if a state degenerates a rod (no frame).
  Design deformedStructure(const Eigen::VectorXd& x) const;

  // ---- Design sensitivities (mechanics/modulus_sensitivity.cpp) -----------------------------
  // The design variables are the control values of every rod's modulus field E(u) (the design's
  // geometry::BSplineField), rod after rod in design order: modulusVariableCount() of them, rod
  // r's first at modulusVariableOffset(r) (std::out_of_range for r > rodCount()).
  std::size_t modulusVariableCount() const;
  std::size_t modulusVariableOffset(std::size_t rod) const;
  // Replaces rod `rod`'s modulus field (MPa) by one with the same degree and knots (so the
  // discretization, chosen for the old field, stays the same) and new control values; the
  // residual scales follow its largest value. Not thread-safe (the only non-const member).
  // std::out_of_range for a bad rod index, std::invalid_argument for another degree or knot
  // vector or a value that is not finite and positive at a collocation point.
  void setModulus(std::size_t rod, const geometry::BSplineField& modulus);
  // dF/dE: the derivative of the scaled residual at (x, load) with respect to the modulus
  // control values (unknownCount() rows, modulusVariableCount() columns), the residual scales held
  // fixed. The residual is linear in E at every point, so this is exact; at a solution (F = 0) it
  // is also the derivative with the scales following E. std::invalid_argument for x of the wrong size.
  Eigen::SparseMatrix<double> modulusJacobian(const Eigen::VectorXd& x, double load) const;
  // The collocation parameters of rod `rod` (the design's parameter), ends included.
  const std::vector<double>& collocationPoints(std::size_t rod) const;
  // The parameters of rod `rod`'s interior sites (T-joints, interior loads and supports), increasing;
  // each is also a collocation point, where the basis is C0 and stateJet() gives the side above it.
  const std::vector<double>& interiorSites(std::size_t rod) const;
  // The state at one parameter as a linear function of x, for shape objectives: r(u), r'(u),
  // q(u), q'(u) (u-derivatives, q not normalized) and, per control point k of the basis there,
  // the index of its first unknown (position at +0..2, quaternion at +3..6) and its basis
  // function's value and u-derivative: r(u) = sum value[k] x[first[k] + 0..2], and so on.
  struct StateJet {
    Eigen::Vector3d r, dr;
    Eigen::Vector4d q, dq;
    std::vector<std::size_t> first;
    std::vector<double> value, d1;
  };
  // std::out_of_range for a bad rod index, std::invalid_argument for x of the wrong size.
  StateJet stateJet(const Eigen::VectorXd& x, std::size_t rod, double u) const;

  // ---- Memory (mechanics/memory_estimate.cpp) -------------------------------------------------
  // Bytes this problem holds, and estimated peak bytes of one solve of it (SolveMemory): known
  // before the Jacobian is assembled or factorized, for checking against a memory budget.
  SolveMemory memoryEstimate() const;

private:
  const geometry::BSplineField& modulus(std::size_t rod) const;
  std::unique_ptr<detail::DiscreteStructure> structure_;
  // Per rod the field setModulus gave (empty: none yet, the design's); modulus_sensitivity.cpp.
  std::vector<std::optional<geometry::BSplineField>> moduli_;
};

// LU factorization of a Jacobian, on SuiteSparse's KLU. The first factorize() of a sparsity pattern
// orders it (AMD); later calls with the same pattern reuse that ordering and, while the pivots stay
// sound (the pivot ratio within 1e4 of a fresh factorization's), the pivot sequence, which halves
// the cost. Every factorization is of the matrix given: solves are exact up to rounding, not
// approximate.
// factorize() must not run concurrently with anything else on the same object; solve() and
// solveTransposed() may be called from several threads (they are serialized).
class JacobianLU {
public:
  // pivotBlock > 1: rows are paired with columns inside each diagonal block of that size (7 for
  // StaticProblem: a control point's unknowns and equations) by complete pivoting of the block on
  // the first matrix of a pattern, so that the diagonal KLU prefers as pivots is strong.
  explicit JacobianLU(int pivotBlock = 1);
  ~JacobianLU();
  JacobianLU(JacobianLU&&) noexcept;
  JacobianLU& operator=(JacobianLU&&) noexcept;

  enum class Pivoting { Reuse, Fresh };
  // Factorizes `jacobian` (square, compressed, non-empty; else std::invalid_argument), with the
  // previous pivot sequence when asked and still sound, else with fresh partial pivoting. Returns
  // false when it is numerically singular (a zero pivot) or holds a non-finite entry; throws
  // std::runtime_error when KLU itself fails (out of memory).
  bool factorize(const Eigen::SparseMatrix<double>& jacobian, Pivoting pivoting = Pivoting::Reuse);
  // The last factorization kept the previous pivots: if a solve is not accurate enough, factorize
  // again with Pivoting::Fresh.
  bool pivotsReused() const;
  // x with J x = b, and x with J^T x = b (for adjoint sensitivities), J the last matrix factorized.
  // std::logic_error before a successful factorize, std::invalid_argument for a wrong size.
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const;
  Eigen::VectorXd solveTransposed(const Eigen::VectorXd& b) const;
  // Sign of det J: +1 or -1 (0 before a successful factorize).
  int determinantSign() const;
  // ln |det J| (the row scaling KLU applies included); NaN before a successful factorize. Where two
  // eigenvalues cross zero together det J keeps its sign and only its size tells (a dip to zero).
  double logAbsDeterminant() const;
  // min |U_ii| / max |U_ii|: a crude reciprocal condition estimate of J.
  double pivotRatio() const;
  // Entries of L and U in the last factorization (0 before a successful one).
  std::size_t factorEntries() const;
  // KLU's symbolic estimate of the entries of L and U for a matrix of this pattern (AMD's count,
  // diagonal pivots): what a factorization will need, known before it runs. Infinity when KLU
  // cannot analyse it (out of memory).
  static double estimatedFactorEntries(const Eigen::SparseMatrix<double>& pattern);
  // How often the pattern was analysed, and the factorizations with fresh and with reused pivots.
  int analyses() const { return analyses_; }
  int factorizations() const { return factorizations_; }
  int refactorizations() const { return refactorizations_; }

private:
  struct Factors;
  bool samePattern(const Eigen::SparseMatrix<double>& m) const;
  Eigen::VectorXd solve(const Eigen::VectorXd& b, bool transposed) const;
  std::unique_ptr<Factors> factors_;
  int pivotBlock_ = 1;
  int analyses_ = 0, factorizations_ = 0, refactorizations_ = 0;
};

struct SolverOptions {
  int loadSteps = 0;        // 0: the design's mechanics.load_steps
  int maxIterations = 30;   // Newton iterations per load step before the step is cut
  // Converged when the scaled residual's largest entry or the last Newton correction (stepNorm)
  // is below this (the residual below 1e-8 of the full load's scaled size if that is smaller: tiny
  // loads). Rounding keeps the residual of very slender rods near 1e-16 (L / r)^2, so the
  // correction is what tells convergence there.
  double tolerance = 1e-10;
  int maxStepCuts = 16;     // halvings of the planned load step before giving up
  // Once a Newton correction is below 1e-3 of the structure, further corrections reuse the last
  // factorization (chord steps) while each cuts the residual tenfold; off: every step full Newton.
  bool chordSteps = true;
  // After passing a bifurcation (det J changed sign, the critical mode orthogonal to the load),
  // perturb the state along the critical mode and continue on the branch that is stable again.
  bool followStableBranch = false;
  // A critical point found between two load steps is bracketed by bisection (Newton solves) to
  // this width in load factor, and a dip of |det J| with no change of sign (two eigenvalues crossing
  // zero together) by a golden-section search; 1 or more: neither (a dip is then not looked into).
  double criticalLoadTolerance = 1e-3;
};

// A point where an eigenvalue of the tangent crossed zero (bifurcation or limit point): det J changed
// sign between two converged load steps, or |det J| dipped between steps (mechanics/README.md,
// "What the sign cannot show"): to zero as the square of the load distance where two eigenvalues
// cross together (the two buckling modes of a round or square section, which leave det J's sign as
// it was), or towards zero before a branch's end that the load path jumped past (snap-through).
struct CriticalPoint {
  double fromLoad = 0.0, toLoad = 0.0;  // load factors bracketing it (SolverOptions::criticalLoadTolerance)
  int crossings = 1;  // eigenvalues crossing zero there: 2 where det J kept its sign
  enum class Kind { Bifurcation, LimitPoint } kind = Kind::Bifurcation;
  // |psi . dF/dload| / (|psi| |dF/dload|), psi the critical left eigenvector (of J^T): near 0 at a
  // bifurcation (the load does not drive the critical mode), of order 1 at a limit point.
  double loadAlignment = 0.0;
  bool branchSwitched = false;  // followStableBranch moved the solution onto a stable branch here
  // A limit point the load path jumped past onto another branch (snap-through: under load control
  // the structure would snap there), found at the bottom of a dip of |det J| where the branch ends.
  bool snapThrough = false;
};

enum class Stability {
  Stable,        // no critical point passed (det J kept the reference state's sign and never dipped to zero)
  Unstable,      // det J has the opposite sign (an odd number of crossings), or the only critical point
                 // passed was two eigenvalues crossing together
  Undetermined,  // det J is back to the reference sign after more than one critical point
};

struct LoadStepReport {
  int index = 0;                // 1-based count of converged steps
  double loadFactor = 0.0;      // reached by this step
  double increment = 0.0;       // load factor added by this step
  std::vector<double> residuals;  // scaled residual before each Newton iteration and at the end
  int chordIterations = 0;      // of them, corrections with the previous factorization
  int cuts = 0;                 // halvings of the planned step in force when this step converged
  int determinantSign = 1;      // sign of det J here relative to the reference state's
};

struct Solution {
  Eigen::VectorXd state;
  std::vector<LoadStepReport> steps;
  std::vector<CriticalPoint> criticalPoints;
  Stability stability = Stability::Stable;
  // LU of the Jacobian at `state` and load 1: for adjoint sensitivities (solveTransposed).
  std::shared_ptr<const JacobianLU> tangent;
  int newtonIterations = 0;  // with a new Jacobian
  int chordIterations = 0;   // reusing the last factorization once the corrections are small
  int factorizations = 0, refactorizations = 0;  // with fresh pivots, with reused pivots
  int pivotRenewals = 0;  // solves with reused pivots not accurate enough, done again with fresh ones
  double factorizeSeconds = 0.0, assembleSeconds = 0.0, totalSeconds = 0.0;
};

// Solves from the reference state up to load factor 1. `onStep` is called after every converged
// load step with its report and state. Throws ConvergenceError, or MechanicsError when the
// reference state's Jacobian is singular (a mechanism).
using StepCallback = std::function<void(const LoadStepReport&, const Eigen::VectorXd& state)>;
Solution solve(const StaticProblem& problem, const SolverOptions& options, int designLoadSteps,
               const StepCallback& onStep = {});

// Newton at load factor 1 from `start` (a solution of another discretization, transferred), with
// the load path of solve() as the fallback when that does not converge. The result has one step
// (or the path's), no critical points (none are looked for), and stability from the sign of det J
// at the end. Throws as solve() does, std::invalid_argument for a start of the wrong size.
Solution solveFrom(const StaticProblem& problem, const Eigen::VectorXd& start, const SolverOptions& options,
                   int designLoadSteps);

// ---- Converged answers: an error estimate and refinement --------------------------------------

struct AccuracyOptions {
  // Largest estimated position error of a centerline point over the largest displacement. The
  // automatic span counts aim at it, and refinement goes on until the estimate meets it.
  double tolerance = 1e-4;
  int maxRefinements = 2;  // doublings of every rod's spans at most
  bool estimate = true;    // false: a single solve on the discretization as given, no estimate
};

struct ErrorEstimate {
  bool available = false;
  double positionError = 0.0;        // mm: estimated largest error of a centerline point's displacement
  double largestDisplacement = 0.0;  // mm: largest displacement of a centerline point
  double relative = 0.0;             // positionError / max(largestDisplacement, 1e-6 structure size)
  // Observed ratio of the differences between successive levels (0 until two comparisons were
  // made, when a ratio of 2^(order - 2) per halving of the spans is assumed).
  double ratio = 0.0;
  std::size_t comparedUnknowns = 0;  // size of the discretization compared with
  std::string note;                  // why no estimate is available, or what it had to do without (a coarser
                                     // solve failed, a finer one could not be made, rods at the span limit)
};

struct Simulation {
  std::unique_ptr<StaticProblem> problem;  // the discretization `solution` belongs to
  Solution solution;
  ErrorEstimate estimate;
  std::optional<UnderResolvedRod> underResolved;  // of `problem`, the final level (estimated or not)
  int refinements = 0;
  double seconds = 0.0;  // wall time of all solves, the estimate's included
};

// Called by simulate() before each solve with the problem about to be solved.
enum class Level {
  Path,        // the first solve, along the load path
  Estimate,    // half the spans, for the error estimate
  Refinement,  // every rod's spans doubled
};
using LevelCallback = std::function<void(Level, const StaticProblem&)>;

// Solves `design` on `discretization` (its tolerance set to accuracy.tolerance) along the load
// path, then estimates the discretization error: the largest difference of centerline
// displacements from a solve with half the spans per rod, divided by (ratio - 1) (Richardson). While the estimate
// is above the tolerance, every rod's spans are doubled and the problem solved again from the
// previous solution (up to maxRefinements), the ratio now observed. The path history (steps,
// critical points) is the first level's. When the solve with half the spans fails, the estimate
// compares the first level with a solve on twice the spans instead (one of the refinements), which is
// then the answer; a finer solve that fails leaves the refinement where it was, and no estimate if
// there was none (ErrorEstimate::note says so). Throws as StaticProblem
// and solve() do for the first level, and std::invalid_argument for out-of-range accuracy options.
Simulation simulate(const Design& design, Discretization discretization, const SolverOptions& solver,
                    int designLoadSteps, const AccuracyOptions& accuracy = {}, const StepCallback& onStep = {},
                    const LevelCallback& onLevel = {});

// One load case's structure: `design`'s rods and "mechanics" block with the case's supports, loads
// and load steps in place of the block's own, and no load cases (what the optimizer solves per case).
Design loadCaseStructure(const Design& design, const LoadCase& loadCase);

// Every check a solve would make before it starts (StaticProblem's, on the default discretization:
// the places, supports and joints, and the solver's limits: unknowns, weights, tolerances), for the
// design's own "mechanics" block (what simulate solves; skipped when load cases stand in for it and it
// has no supports or loads) and for each load case's structure (what optimize solves); nothing is
// solved. Throws MechanicsError as StaticProblem does, a case's message as `FILE: load case "NAME"
// (PATH): JSON.PATH: what`. For a design without a "mechanics" block there is nothing to check.
void checkMechanics(const Design& design);

}  // namespace rodfab::mechanics
