#include "slicer/simulation_summary.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rodfab::cli {

namespace {

std::string basisSummary(const mechanics::StaticProblem& problem, const mechanics::Discretization& asked) {
  const mechanics::Discretization& d = problem.discretization();
  const auto [lo, hi] = std::minmax_element(d.perRod.begin(), d.perRod.end());
  const std::string range = *lo == *hi ? std::to_string(*lo) : std::to_string(*lo) + ".." + std::to_string(*hi);
  const bool automatic = d.degree > 0 ? asked.spans == 0 : asked.refine < 0;
  const std::string how = automatic ? "automatic" : d.degree > 0 ? "--spans" : "--refine";
  const std::string basis = d.degree > 0 ? "degree " + std::to_string(d.degree) + ", " + range + " spans per rod"
                                         : "the design's own, " + range + " solver spans per design span";
  return basis + " (" + how + "); " + std::to_string(problem.unknownCount()) + " unknowns";
}

nlohmann::json estimateJson(const mechanics::Simulation& sim, const mechanics::AccuracyOptions& accuracy) {
  const mechanics::ErrorEstimate& e = sim.estimate;
  if (!accuracy.estimate) return nullptr;
  nlohmann::json j{{"available", e.available}, {"tolerance", accuracy.tolerance}, {"refinements", sim.refinements}};
  if (!e.note.empty()) j["note"] = e.note;
  if (!e.available) return j;
  j.update({{"position_error_mm", e.positionError}, {"relative", e.relative}, {"within_tolerance", e.relative <= accuracy.tolerance},
            {"compared_unknowns", e.comparedUnknowns}, {"observed_ratio", e.ratio}});
  return j;
}

// What the stability verdict cannot see here: the structure's blind spot (follower loads), or a path
// of fewer than 10 load steps, between which |det J| can dip and rise unseen (a round column at 6 Pcr
// with two steps was "stable").
constexpr std::size_t kStepsSeeingDips = 10;
std::optional<std::string> stabilityCaveat(const mechanics::StaticProblem& problem, std::size_t pathSteps) {
  if (std::optional<std::string> blind = problem.stabilityBlindSpot()) return blind;
  if (pathSteps >= kStepsSeeingDips) return std::nullopt;
  return "det J was looked at after " + std::to_string(pathSteps) + " load step" + (pathSteps == 1 ? "" : "s") +
         " only: two modes crossing together, or a snap-through, can hide within steps that coarse (--load-steps " +
         std::to_string(kStepsSeeingDips) + " or more)";
}

nlohmann::json caveatJson(const std::optional<std::string>& caveat) {
  return caveat ? nlohmann::json(*caveat) : nlohmann::json(nullptr);
}

// The accuracy line, and the warning when the estimate is missing or above the tolerance.
void printAccuracy(const mechanics::ErrorEstimate& e, const mechanics::AccuracyOptions& accuracy) {
  if (!accuracy.estimate) std::printf("accuracy:  not estimated (--no-estimate)\n");
  else if (!e.available) std::printf("accuracy:  no estimate: %s\n", e.note.c_str());
  else std::printf("accuracy:  estimated position error %.3g mm = %.2g of the largest displacement (--accuracy %g)%s%s\n",
                   e.positionError, e.relative, accuracy.tolerance, e.note.empty() ? "" : "; ", e.note.c_str());
  if (accuracy.estimate && (!e.available || e.relative > accuracy.tolerance))
    std::fprintf(stderr, "warning: the discretization error may exceed --accuracy %g; give more --spans (or --max-refinements)\n",
                 accuracy.tolerance);
}

// The stability line, and the warning when the final state is not known to be stable.
void printStability(const mechanics::Solution& sol, const std::optional<std::string>& caveat, bool followStableBranch) {
  std::printf("stability: %s", stabilityName(sol.stability));
  if (caveat && sol.stability == mechanics::Stability::Stable) std::printf(" as far as det J tells (%s)", caveat->c_str());
  for (const auto& c : sol.criticalPoints) std::printf("; %s", describeCriticalPoint(c).c_str());
  std::printf("\n");
  const bool paired = !sol.criticalPoints.empty() && sol.criticalPoints.back().crossings == 2;
  if (sol.stability == mechanics::Stability::Unstable)
    std::fprintf(stderr, "warning: the final state is an unstable equilibrium (%s along the path)%s\n",
                 paired ? "two modes crossed zero together" : "det J changed sign",
                 paired ? "; --follow-stable-branch does not continue past two modes at once: load the design off its symmetry "
                          "(or add a small lateral load) to follow the buckled branch"
                 : followStableBranch ? "" : "; --follow-stable-branch continues on the stable (buckled) branch");
  else if (sol.stability == mechanics::Stability::Undetermined)
    std::fprintf(stderr, "warning: %zu critical points passed: the final state may be unstable\n", sol.criticalPoints.size());
  for (const auto& c : sol.criticalPoints)
    if (c.snapThrough)
      std::fprintf(stderr, "warning: the structure snaps through near load factor %.4g (a limit point: its branch ends there); "
                   "the load path jumped onto another branch, which the real structure reaches dynamically, and other "
                   "--load-steps may land on another one\n", c.fromLoad);
}

}  // namespace

const char* stabilityName(mechanics::Stability s) {
  switch (s) {
    case mechanics::Stability::Stable: return "stable";
    case mechanics::Stability::Unstable: return "unstable";
    case mechanics::Stability::Undetermined: return "undetermined";
  }
  return "?";
}

std::string describeCriticalPoint(const mechanics::CriticalPoint& c) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s%s between load factors %.6g and %.6g%s%s",
                c.kind == mechanics::CriticalPoint::Kind::Bifurcation ? "bifurcation" : "limit point",
                c.crossings == 2 ? " of two modes at once (det J kept its sign)" : "", c.fromLoad, c.toLoad,
                c.branchSwitched ? " (continued on the stable branch)" : "",
                c.snapThrough ? " (snap-through: the load path jumped past it onto another branch)" : "");
  return buf;
}

nlohmann::json criticalPointsJson(const std::vector<mechanics::CriticalPoint>& points) {
  nlohmann::json critical = nlohmann::json::array();
  for (const auto& c : points)
    critical.push_back({{"kind", c.kind == mechanics::CriticalPoint::Kind::Bifurcation ? "bifurcation" : "limit_point"},
                        {"from_load", c.fromLoad}, {"to_load", c.toLoad}, {"crossings", c.crossings},
                        {"load_alignment", c.loadAlignment},
                        {"branch_switched", c.branchSwitched}, {"snap_through", c.snapThrough}});
  return critical;
}

void printLoadStep(const mechanics::LoadStepReport& r) {
  std::printf("step %3d  load %.4f  Newton:", r.index, r.loadFactor);
  for (double v : r.residuals) std::printf(" %.1e", v);
  std::printf("  (%zu iterations", r.residuals.size() - 1);
  if (r.chordIterations > 0) std::printf(", %d with the previous factorization", r.chordIterations);
  std::printf(")");
  if (r.cuts > 0) std::printf("  [step cut %d time%s: +%.4g]", r.cuts, r.cuts > 1 ? "s" : "", r.increment);
  std::printf("\n");
  std::fflush(stdout);
}

nlohmann::json loadStepJson(const mechanics::LoadStepReport& r) {
  return {{"step", r.index}, {"load_factor", r.loadFactor}, {"increment", r.increment}, {"residuals", r.residuals},
          {"chord_iterations", r.chordIterations}, {"cuts", r.cuts}, {"det_sign", r.determinantSign}};
}

void printSolverLevel(mechanics::Level level, const mechanics::StaticProblem& p, const mechanics::Discretization& asked) {
  if (level == mechanics::Level::Path)
    std::printf("structure: %zu joints, %zu supports\nbasis:     %s\n", p.jointCount(), p.supportCount(),
                basisSummary(p, asked).c_str());
  else if (level == mechanics::Level::Estimate)
    std::printf("estimate:  solving with half the spans (%zu unknowns)\n", p.unknownCount());
  else
    std::printf("refining:  every rod's spans doubled (%zu unknowns)\n", p.unknownCount());
  std::fflush(stdout);
}

LargestDisplacement largestDisplacement(const mechanics::Design& design, const mechanics::StaticProblem& problem,
                                        const Eigen::VectorXd& x) {
  const Eigen::VectorXd& x0 = problem.referenceState();
  LargestDisplacement largest;
  for (std::size_t r = 0; r < problem.rodCount(); ++r) {
    const auto& c = design.rods[r].centerline();
    for (int i = 0; i <= 64; ++i) {
      const double u = c.domainBegin() + (c.domainEnd() - c.domainBegin()) * i / 64;
      const double d = (problem.position(x, r, u) - problem.position(x0, r, u)).norm();
      if (d > largest.mm) largest.mm = d, largest.rod = design.rods[r].name();
    }
  }
  return largest;
}

nlohmann::json simulationJson(const SimulationSummary& s) {
  const mechanics::Solution& sol = s.simulation.solution;
  const mechanics::StaticProblem& p = *s.simulation.problem;
  return {{"design", s.design}, {"output", s.output}, {"rods", p.rodCount()}, {"joints", p.jointCount()},
          {"supports", p.supportCount()}, {"unknowns", p.unknownCount()},
          {"discretization", {{"degree", p.discretization().degree}, {"spans_per_rod", p.discretization().perRod}}},
          {"load_steps", s.history}, {"newton_iterations", sol.newtonIterations}, {"chord_iterations", sol.chordIterations},
          {"stability", stabilityName(sol.stability)}, {"stability_blind_spot", caveatJson(stabilityCaveat(p, s.history.size()))},
          {"critical_points", criticalPointsJson(sol.criticalPoints)},
          {"error_estimate", estimateJson(s.simulation, s.settings.accuracy)},
          {"under_resolved", underResolvedJson(s.simulation.underResolved)},
          {"largest_displacement_mm", s.largest.mm}, {"largest_displacement_rod", s.largest.rod},
          {"seconds", {{"total", s.simulation.seconds}, {"assemble", sol.assembleSeconds}, {"factorize_and_solve", sol.factorizeSeconds}}},
          {"memory", {{"estimate_bytes", s.memoryEstimate}}}};
}

void printSimulationSummary(const SimulationSummary& s) {
  const mechanics::Simulation& sim = s.simulation;
  const mechanics::Solution& sol = sim.solution;
  std::printf("converged: %zu load steps, %d Newton iterations (+%d reusing a factorization), %.3f s (assembly %.3f s, "
              "LU %.3f s)\n", sol.steps.size(), sol.newtonIterations, sol.chordIterations, sim.seconds, sol.assembleSeconds,
              sol.factorizeSeconds);
  if (sim.refinements > 0) std::printf("basis:     refined %d time%s: %s\n", sim.refinements, sim.refinements > 1 ? "s" : "",
                                       basisSummary(*sim.problem, s.settings.discretization).c_str());
  printAccuracy(sim.estimate, s.settings.accuracy);
  warnUnderResolved(sim.underResolved, "",
                    "give more --spans (--refine on the design's basis) or leave them to the automatic choice");
  printStability(sol, stabilityCaveat(*sim.problem, s.history.size()), s.settings.solver.followStableBranch);
  if (s.largest.rod.empty()) std::printf("largest displacement: 0 mm (nothing moved)\n");
  else std::printf("largest displacement: %.6g mm (rod '%s')\n", s.largest.mm, s.largest.rod.c_str());
  std::printf("wrote:     %s\n", s.output.c_str());
}

nlohmann::json underResolvedJson(const std::optional<mechanics::UnderResolvedRod>& u) {
  if (!u) return nullptr;
  const nlohmann::json needed = std::isfinite(u->needed) ? nlohmann::json(static_cast<long long>(std::ceil(u->needed))) : nlohmann::json(nullptr);
  return {{"rod", u->rod}, {"degree", u->degree}, {"spans", u->spans}, {"spans_needed", needed}, {"relative_error", u->relative}};
}

// Said whatever the error estimate claims: it compares levels that lock alike, so it cannot see this.
void warnUnderResolved(const std::optional<mechanics::UnderResolvedRod>& u, const std::string& context, const std::string& remedy) {
  if (!u) return;
  std::fprintf(stderr,
               "warning: %s%s has %d spans of degree %d where the a priori model asks about %.0f for even %g %% accuracy "
               "(mechanics/README.md, \"Automatic spans\"): collocation still locks on it, so the answer can be far off "
               "(even bent the wrong way) and the error estimate far too small; %s\n",
               context.c_str(), u->rod.c_str(), u->spans, u->degree, std::ceil(u->needed), 100 * u->relative, remedy.c_str());
}

}  // namespace rodfab::cli
