// Static equilibrium of rod structures: geometrically exact Cosserat rods discretized by
// isogeometric collocation (centerline r and quaternion q on each rod's NURBS basis, collocated at
// the Greville abscissae), rigid joints between rod ends, Newton's method with load stepping.
//
// Units follow the design file: mm, MPa, N, N mm. Loads and prescribed displacements and rotations
// grow linearly with the load factor from 0 (the design as drawn, stress-free) to 1.
#pragma once

#include "geometry/rod.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <cstddef>
#include <functional>
#include <memory>
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

// Newton did not converge even after cutting the load step `maxStepCuts` times.
class ConvergenceError : public std::runtime_error {
public:
  ConvergenceError(const std::string& message, double lastConvergedLoad)
      : std::runtime_error(message), lastConvergedLoad_(lastConvergedLoad) {}
  double lastConvergedLoad() const { return lastConvergedLoad_; }

private:
  double lastConvergedLoad_;
};

// The discrete nonlinear system F(x, load) = 0. x holds, rod after rod, each control point's
// position (3) and quaternion (4); there are as many equations as unknowns: 7 per collocation
// point (force and moment balance, unit quaternion), with the rows of each rod's two end points
// replaced by the joint, support and end-load conditions of the node the end belongs to.
// How each rod's centerline becomes the solver's basis.
struct Discretization {
  // 0 keeps each centerline's degree and NURBS basis, refined exactly by inserting `refine` knots
  // into every span. Another degree (4 is a good choice: even degrees converge at order p, odd
  // ones at p - 1) rebuilds each rod as a B-spline of that degree with uniform knots, interpolating
  // the design's centerline at the new collocation points (geometric error of order h^(degree+1)).
  int degree = 0;
  int refine = 0;  // knots inserted per design span
  int spans = 0;   // with `degree`: spans per rod; 0 gives the design's span count times (refine + 1), at least 8
};

class StaticProblem {
public:
  // Throws MechanicsError.
  explicit StaticProblem(const geometry::RodStructure& structure, const Discretization& discretization = {});
  ~StaticProblem();
  StaticProblem(StaticProblem&&) noexcept;
  StaticProblem& operator=(StaticProblem&&) noexcept;

  std::size_t unknownCount() const;
  std::size_t rodCount() const;
  std::size_t jointCount() const;    // nodes where two or more rod ends meet
  std::size_t supportCount() const;
  const std::string& source() const;

  // The undeformed configuration (a solution at load 0).
  const Eigen::VectorXd& referenceState() const;

  // Scaled residual (dimensionless: forces by E I / L^2 and moments by E I / L of their rod,
  // positions by the rod length) and, when `jacobian` is given, its exact derivative.
  // Parallel over collocation points (TBB); the result does not depend on the thread count.
  void evaluate(const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                Eigen::SparseMatrix<double>* jacobian = nullptr) const;

  // Centerline point and rotation of rod `rod` at parameter u in state x.
  Eigen::Vector3d position(const Eigen::VectorXd& x, std::size_t rod, double u) const;
  Eigen::Matrix3d rotation(const Eigen::VectorXd& x, std::size_t rod, double u) const;
  // Largest change of x in units of the structure: positions / its size, quaternions as they are.
  double stepNorm(const Eigen::VectorXd& dx) const;

  // The structure in state x as a design: the (refined) centerlines with the solved control points
  // and an `orientation` quaternion spline per rod; sections, caps and moduli as in the input.
  geometry::RodStructure deformedStructure(const Eigen::VectorXd& x) const;

private:
  std::unique_ptr<detail::DiscreteStructure> structure_;
};

struct SolverOptions {
  int loadSteps = 0;        // 0: the design's mechanics.load_steps
  int maxIterations = 30;   // Newton iterations per load step before the step is cut
  // Converged when the scaled residual's largest entry or the last Newton correction (stepNorm)
  // is below this. Rounding keeps the residual of very slender rods near 1e-16 (L / r)^2, so the
  // correction is what tells convergence there.
  double tolerance = 1e-10;
  int maxStepCuts = 16;     // halvings of one load step before giving up
};

struct LoadStepReport {
  int index = 0;                // 1-based count of converged steps
  double loadFactor = 0.0;      // reached by this step
  std::vector<double> residuals;  // scaled residual before each Newton iteration and at the end
  int cuts = 0;                 // halvings of the step needed to reach this load factor
};

struct Solution {
  Eigen::VectorXd state;
  std::vector<LoadStepReport> steps;
  int newtonIterations = 0;
  double factorizeSeconds = 0.0, assembleSeconds = 0.0, totalSeconds = 0.0;
};

// Solves from the reference state up to load factor 1. `onStep` is called after every converged
// load step with its report and state. Throws ConvergenceError or MechanicsError (a singular
// Jacobian: a mechanism).
using StepCallback = std::function<void(const LoadStepReport&, const Eigen::VectorXd& state)>;
Solution solve(const StaticProblem& problem, const SolverOptions& options, int designLoadSteps,
               const StepCallback& onStep = {});

}  // namespace rodfab::mechanics
