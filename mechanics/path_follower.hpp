// Internal to mechanics/: the load path of one solve (solver.cpp: Newton, load steps, sign changes of
// det J, branch switching; path_follower_dips.cpp: the critical points only dips of |det J| show).
#pragma once

#include "mechanics/mechanics.hpp"

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace rodfab::mechanics::detail {

enum class Outcome { Converged, Diverged };

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
  // A converged state on the path, with ln |det J| and the relative sign of det J there.
  struct Sample {
    double load = 0.0, logDet = 0.0;
    int sign = 1;
    Eigen::VectorXd state;
  };
  void checkCriticalPoint(Eigen::VectorXd& x, double fromLoad, double toLoad);
  CriticalPoint bisectCrossing(Sample low, Sample high, bool mayJump);
  bool jumpedAcross(const Sample& outerLow, const Sample& outerHigh, const Sample& low, const Sample& high) const;
  Eigen::VectorXd criticalMode(bool transposed) const;
  double loadAlignment(const Eigen::VectorXd& x, double load, const Eigen::VectorXd& psi) const;
  bool switchBranch(Eigen::VectorXd& x, double load);
  bool jumpPastBranchEnd(Eigen::VectorXd& x, double load, double smallest, double planned, double& target, LoadStepReport& report);
  bool factorizeAt(const Eigen::VectorXd& x, double load, JacobianLU::Pivoting pivoting = JacobianLU::Pivoting::Reuse);
  void classify(CriticalPoint& point, const Eigen::VectorXd& x, double load);
  void finish();

  // Dips of |det J| (path_follower_dips.cpp).
  Sample sampleHere(const Eigen::VectorXd& x, double load) const;
  std::optional<Sample> sampleAt(Eigen::VectorXd x, double load, int iterations = 12);
  void lookForDips(const Eigen::VectorXd& x, double load, bool otherBranch);
  void lookForDipAtEnd();
  void searchDip(Sample lo, Sample best, Sample hi);
  bool narrowDip(Sample& lo, Sample& best, Sample& hi, double width);
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
  Eigen::VectorXd uncutState_;  // where the last step of the planned size ended (jumpPastBranchEnd)
  double uncutLogDet_ = 0.0;     // ln |det J| there
  Solution solution_;
};

}  // namespace rodfab::mechanics::detail
