// Inverse design: the modulus field E(u) of every rod that makes a structure take target shapes
// under its training loads (the published "4D printing design optimization problem"):
//
//   min over E0 <= E_k <= E1 of g(E) = sum over cases c of w_c sum over rods r with a target of
//     C_r / (2 L_r^2) sum_i |r(tau_i) - r_t(tau_i)|^2 + C_k L_r^2 / 2 sum_i |kappa(tau_i) - kappa_t(tau_i)|^2
//
// subject to equilibrium F(x_c; E) = 0 in every case, tau_i the rod's collocation points, L_r its
// length, kappa the material curvature per deformed arc length (axial(R^T dR/ds)). E(u) per rod is
// a clamped uniform B-spline on the centerline's parameter domain; its control values are the
// design variables. Sensitivities are adjoint: one transposed solve per case with the Newton
// factorization at the solution. The optimizer is L-BFGS-B (LBFGS++) on log E (or E) scaled to [0, 1].
//
// Units: mm, MPa, N. Not thread-safe: one DesignProblem per thread (each solve is parallel inside).
#pragma once

#include "geometry/rod.hpp"
#include "mechanics/mechanics.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::optimize {

// A problem that cannot be set up (no load case with a target, a target rod that is not in the
// design) or a load case whose equilibrium cannot be found; what() names the case or JSON path.
class OptimizeError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

// The optimizer's variables: t in [0, 1] per control value, E = E0 + t (E1 - E0), or
// E = E0 (E1 / E0)^t (logarithmic: equal steps are equal ratios of E).
enum class Scaling { Linear, Logarithmic };

// The bounded optimizer: L-BFGS-B (LBFGS++, More-Thuente line search; an iteration is one line
// search), or NLopt's MMA or CCSAQ (the method of moving asymptotes and its conservative
// quadratic variant; an iteration is one evaluation, maxIterations bounds the evaluations).
enum class Method { LbfgsB, Mma, Ccsaq };

struct Settings {
  double positionWeight = 1.0;   // C_r (dimensionless: positions are divided by the rod length)
  double curvatureWeight = 1.0;  // C_k (dimensionless: curvatures are multiplied by the rod length)
  int modulusControls = 4;       // control values per rod, 1..64
  int modulusDegree = 3;         // 1..7, lowered to modulusControls - 1 when above it (0 for one control)
  double lowerMpa = 8.0, upperMpa = 190.0;  // bounds; the CLI takes them from the calibration
  int maxIterations = 200;       // L-BFGS-B iterations
  double tolerance = 1e-7;       // converged when the projected gradient of g / g0 (in t in [0, 1], see Scaling) is below
  double objectiveTolerance = 0.0;  // also stop when g / g0 falls below this (0: never)
  // Logarithmic by default: where only ratios of E set the shape (displacement-driven cases) g is
  // flat along E -> a E, and equal steps in log E condition that far better (optimize/README.md).
  Scaling scaling = Scaling::Logarithmic;
  Method method = Method::LbfgsB;  // L-BFGS-B by default: optimize/README.md compares the three
  // The discretization is resolved once, for the starting design, and kept for every solve.
  mechanics::Discretization discretization;
  mechanics::SolverOptions solver;
};

// Applies a design's "optimize" block (positionWeight ... tolerance; bounds when given) to settings.
void applySpec(const mechanics::OptimizeSpec& spec, Settings& settings);

struct CaseObjective {
  std::string name;
  double weight = 1.0;
  double position = 0.0, curvature = 0.0;  // the two terms, weight applied
  double total() const { return position + curvature; }
};

struct Evaluation {
  double objective = 0.0;
  std::vector<CaseObjective> cases;
  Eigen::VectorXd gradient;  // dg/dE_k (1 / MPa); empty when not asked for
  int newtonIterations = 0;  // over all cases, for this evaluation
};

// The discretization error of a case's equilibrium (mechanics::simulate's Richardson estimate on
// the optimizer's discretization, no refinement).
struct CaseAccuracy {
  std::string name;
  mechanics::ErrorEstimate estimate;  // available == false with a note when it could not be made
  std::optional<mechanics::UnderResolvedRod> underResolved;  // StaticProblem::leastResolvedRod at the optimum
  // What the load path from the drawn shape at the optimum's E(s) met (mechanics::solve): its critical
  // points and the final state's stability; none when that solve did not converge. The optimizer's
  // own solves continue from the previous E(s) and look for neither.
  std::optional<mechanics::Stability> stability;
  std::vector<mechanics::CriticalPoint> criticalPoints;
};

// The training cases of a design, each a discretized structure with its targets.
class DesignProblem {
public:
  // `design` must carry mechanics.loadCases with at least one target. Throws OptimizeError (named
  // case or path), mechanics::MechanicsError, std::invalid_argument for settings out of range.
  DesignProblem(const mechanics::Design& design, const Settings& settings);
  ~DesignProblem();
  DesignProblem(DesignProblem&&) noexcept;
  DesignProblem& operator=(DesignProblem&&) noexcept;

  const Settings& settings() const;
  std::size_t variableCount() const;  // modulusControls x rods
  std::size_t caseCount() const;
  std::size_t rodCount() const;
  std::size_t unknownCount() const;  // of one case's discretization
  const mechanics::StaticProblem& caseProblem(std::size_t c) const;

  // The design's own E(u) in the optimizer's basis, clamped to the bounds: its control values when
  // it is a B-spline of that basis (an optimized design, so optimizing again resumes where it
  // stopped), else its values at the basis' Greville abscissae (exact for a constant E).
  Eigen::VectorXd startingModulus() const;
  // g and (when `gradient`) dg/dE at the control values `modulus` (MPa, variableCount(), within
  // (0, inf)). Each case's Newton solve starts from its previous solution (continuation in E),
  // falling back to the load path; a case that still fails throws OptimizeError naming it.
  Evaluation evaluate(const Eigen::VectorXd& modulus, bool gradient = true);
  // The equilibrium states of the last evaluate(), per case.
  const Eigen::VectorXd& state(std::size_t c) const;
  // How accurate the equilibria at `modulus` are: per case, a fresh solve along the load path on the
  // optimizer's discretization (whose critical points and stability are kept) and one with twice the
  // spans from it (Newton at full load); the
  // largest difference d of centerline displacements gives the optimizer's level's error
  // d r / (r - 1), r = 2^(order - 2) (optimize/README.md), at about three solves' cost. `poll`
  // (may be empty) is called before each case, after each load step and before the finer solve;
  // what it throws (common::Interrupted) passes through. A case whose solves do not converge gets
  // an estimate marked unavailable; throws mechanics::MechanicsError otherwise.
  std::vector<CaseAccuracy> accuracyAt(const Eigen::VectorXd& modulus, const std::function<void()>& poll = {}) const;
  // The design with each rod's modulus replaced by the B-spline with control values `modulus`.
  mechanics::Design designWith(const Eigen::VectorXd& modulus) const;

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The optimized design as written to `outputFile`: problem.designWith(modulus) with `design`'s
// optimize block, each {"design": PATH} target (relative to `designFile`'s folder) rewritten
// relative to `outputFile`'s folder; absolute paths are kept. `design` is the one `problem` was made from.
mechanics::Design optimizedDesign(const DesignProblem& problem, const Eigen::VectorXd& modulus, const mechanics::Design& design,
                                  const std::filesystem::path& designFile, const std::filesystem::path& outputFile);

// Where an optimization starts: the design's own E(u) (DesignProblem::startingModulus), or one
// modulus everywhere ("uniform material", as the published optimizations start).
struct Start {
  bool uniform = false;
  double mpa = 0.0;  // with `uniform`: the modulus (MPa); 0: the geometric mean of the bounds
};
// "design", "uniform" or "uniform=MPa" (MPa a finite number > 0); nullopt for anything else.
std::optional<Start> parseStart(const std::string& text);
// The control values `start` stands for on `problem`. Throws OptimizeError naming --start when a
// uniform modulus lies outside the settings' bounds.
Eigen::VectorXd startingModulus(const DesignProblem& problem, const Start& start);

struct Iteration {
  int index = 0;                 // 0: the start
  double objective = 0.0;        // g
  double relative = 1.0;         // g / g0
  double projectedGradient = 0.0;  // infinity norm, of g / g0 in the optimizer's variables t in [0, 1]
  int newtonIterations = 0;      // since the previous report
  double seconds = 0.0;          // wall time since the start
};

struct Result {
  Eigen::VectorXd modulus;  // the best control values found (MPa)
  Evaluation initial, final;
  std::vector<Iteration> history;
  int iterations = 0;
  int evaluations = 0;
  // L-BFGS-B's line searches that LBFGS++'s More-Thuente gave up on and that took their lowest
  // trial with sufficient decrease instead (optimize/README.md: a bug of the Debian LBFGS++ 0.1.0)
  int lineSearchFallbacks = 0;
  // "converged", "objective below tolerance", "iteration limit", "line search: ..."; with L-BFGS-B,
  // " (after N restarts of L-BFGS-B from the best point)" when LBFGS++ gave up N times on the way
  std::string stopReason;
  double seconds = 0.0;
};

// Minimizes g from `start` (startingModulus() when empty) within the settings' bounds by the
// settings' method.
// `onIteration` is called at the start and after every iteration; an exception it throws (for
// example common::Interrupted) passes through. Throws as DesignProblem::evaluate.
Result optimize(DesignProblem& problem, const std::function<void(const Iteration&)>& onIteration = {},
                Eigen::VectorXd start = {});

// The convergence plot: g / g0 against iteration on a log axis (960 x 640 PNG, cairo), `title`
// above it. Written under a temporary name and renamed (common::writeFileAtomically); throws
// std::runtime_error naming the file, std::invalid_argument for an empty history. The PNG carries a
// tEXt chunk "Software: rodfab optimize".
void writeHistoryPlot(const std::vector<Iteration>& history, const std::filesystem::path& png, const std::string& title = {});
// True when `png` is a regular file written by writeHistoryPlot or writeShapeRender (both carry the
// same tag: what `optimize --plot` and `--render` may replace).
bool isHistoryPlot(const std::filesystem::path& png);

// ---- The shape render (`optimize --render`) ----------------------------------------------------

// A rod as drawn: points along its centerline (mm) and E there (MPa, one per point; empty for a
// target, drawn in one colour).
struct DrawnRod {
  std::vector<Eigen::Vector3d> points;
  std::vector<double> modulusMpa;
};
// One load case's three columns: the target, the deformed shape with the starting modulus and the
// one with the optimized modulus.
struct ShapeColumns {
  std::string name;
  std::vector<DrawnRod> target, start, optimized;
};
// The target rods of a load case, `samplesPerRod` + 1 points each (uniform in their parameter).
std::vector<DrawnRod> drawnTarget(const std::vector<mechanics::TargetRod>& target, int samplesPerRod = 16);
// Every rod of case `c` in the state of `problem`'s last evaluate() (the caller evaluates at
// `modulus` first), with E from the control values `modulus` (MPa, variableCount()).
// std::out_of_range for a bad case, std::invalid_argument for a wrong size.
std::vector<DrawnRod> drawnDeformed(const DesignProblem& problem, std::size_t c, const Eigen::VectorXd& modulus,
                                    int samplesPerRod = 16);
// The render's columns of every load case of `design` (the design `problem` was made from) that has
// a target, in case order: the target and the deformed shape in `problem`'s current state with the
// control values `start`, `optimized` left empty. Call it while the last evaluate() was at `start`
// (the optimizer's first report). Throws as drawnDeformed.
std::vector<ShapeColumns> startingShapes(const mechanics::Design& design, const DesignProblem& problem, const Eigen::VectorXd& start);
// Fills the `optimized` column of startingShapes' `shapes` from `problem`'s current state with the
// control values `modulus` (after optimize(), whose last evaluation is its best point).
void addOptimizedShapes(const mechanics::Design& design, const DesignProblem& problem, const Eigen::VectorXd& modulus,
                        std::vector<ShapeColumns>& shapes);
// The render: per case (at most the first 4) a row per orthographic view (front: x right, z up;
// side: y right, z up; top: x right, y up) of three 300-pixel panels (target in blue; start and
// optimized coloured by E on viridis between `lowerMpa` and `upperMpa`, over the target in pale
// grey), one scale per case, a colour bar in MPa: a 1050 pixel wide RGB PNG, 64 + 1002 per case
// high, tagged like writeHistoryPlot. Polls common::throwIfInterrupted (common::Interrupted) per
// panel; written under a temporary name and renamed (common::writeFileAtomically). Throws
// std::runtime_error naming the file, std::invalid_argument for no case or lowerMpa >= upperMpa.
void writeShapeRender(const std::vector<ShapeColumns>& cases, double lowerMpa, double upperMpa, const std::filesystem::path& png,
                      const std::string& title = {});

}  // namespace rodfab::optimize
