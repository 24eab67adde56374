// DesignProblem: the training cases on a fixed discretization, their solves by continuation in E,
// and the objective's adjoint gradient.
#include "common/memory_budget.hpp"
#include "common/quoted_text.hpp"
#include "mechanics/mechanics_file.hpp"
#include "optimize/objective.hpp"
#include "optimize/optimize.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>

namespace rodfab::optimize {

using detail::RodTarget;

namespace {

// Clamped uniform knots of `count` values of degree p on [begin, end].
std::vector<double> uniformKnots(int p, int count, double begin, double end) {
  std::vector<double> k(p + 1, begin);
  const int spans = count - p;
  for (int i = 1; i < spans; ++i) k.push_back(begin + (end - begin) * i / spans);
  k.insert(k.end(), p + 1, end);
  return k;
}

void checkSettings(const Settings& s) {
  if (s.modulusControls < 2 || s.modulusControls > 64) throw std::invalid_argument("modulus controls: 2..64 expected");
  if (s.modulusDegree < 1 || s.modulusDegree > geometry::kMaxDegree)
    throw std::invalid_argument("modulus degree: 1.." + std::to_string(geometry::kMaxDegree) + " expected");
  if (!(s.lowerMpa > 0) || !(s.upperMpa > s.lowerMpa) || !std::isfinite(s.upperMpa))
    throw std::invalid_argument("modulus bounds: 0 < lower < upper (finite) expected");
  if (!(s.positionWeight >= 0) || !(s.curvatureWeight >= 0) || !std::isfinite(s.positionWeight + s.curvatureWeight) ||
      s.positionWeight + s.curvatureWeight == 0)
    throw std::invalid_argument("objective weights: finite, non-negative, not both zero expected");
  if (s.maxIterations < 0 || !(s.tolerance >= 0) || !(s.objectiveTolerance >= 0))
    throw std::invalid_argument("iterations and tolerances: non-negative expected");
}

// Refuses (common::OutOfMemory), once the first case's problem is built and before the others
// are, a training that would not fit in the memory budget: on top of the process's data now (the
// first case's problem included), every further case's problem (each case keeps its own), then
// the larger of an evaluation's peak (one solve, and dF/dE with its copy of the rods) and of the
// accuracy check's at the end (a case solved again beside a problem with twice the spans, taken
// as twice the size: every rod's band of the Jacobian and factors doubles with its spans).
void requireMemory(const std::string& source, const mechanics::StaticProblem& first, std::size_t cases) {
  const mechanics::SolveMemory m = first.memoryEstimate();
  const double problem = static_cast<double>(m.problem), solve = static_cast<double>(m.solve);
  const double held = static_cast<double>(common::dataBytesInUse()) + static_cast<double>(cases - 1) * problem;
  const double need = held + std::max(solve + problem, problem + static_cast<double>(m.kept) + 2 * (problem + solve));
  common::requireMemory(common::saturatedBytes(need),
                        {.what = "optimizing " + source + " (" + std::to_string(cases) + " load case" + (cases == 1 ? "" : "s") +
                                 " of " + std::to_string(first.unknownCount()) + " unknowns)",
                         .remedy = "train on fewer load cases, a coarser discretization or a smaller design, or raise "
                                   "--max-memory if the machine has more"});
}

}  // namespace

void applySpec(const mechanics::OptimizeSpec& spec, Settings& settings) {
  if (!spec.present) return;
  settings.positionWeight = spec.positionWeight;
  settings.curvatureWeight = spec.curvatureWeight;
  settings.modulusControls = spec.modulusControls;
  settings.modulusDegree = spec.modulusDegree;
  if (spec.boundsMpa) settings.lowerMpa = spec.boundsMpa->first, settings.upperMpa = spec.boundsMpa->second;
  settings.maxIterations = spec.maxIterations;
  settings.tolerance = spec.tolerance;
}

struct DesignProblem::Impl {
  struct Case {
    std::string name, path;
    double weight = 1.0;
    int loadSteps = 10;
    std::unique_ptr<mechanics::Design> structure;  // the rods the problem points to
    std::unique_ptr<mechanics::StaticProblem> problem;
    std::vector<RodTarget> targets;
    Eigen::VectorXd state;
    bool solved = false;
  };
  Settings settings;
  mechanics::Design design;
  int degree = 3;
  std::vector<std::vector<double>> knots;  // per rod, of the optimizer's E(u)
  std::vector<Case> cases;

  geometry::BSplineField field(std::size_t rod, const Eigen::VectorXd& modulus) const {
    const auto n = static_cast<Eigen::Index>(settings.modulusControls);
    const Eigen::VectorXd v = modulus.segment(static_cast<Eigen::Index>(rod) * n, n);
    return geometry::BSplineField(degree, knots[rod], std::vector<double>(v.data(), v.data() + n));
  }
  std::vector<geometry::Rod> rodsWith(const Eigen::VectorXd& modulus) const {
    std::vector<geometry::Rod> rods;
    for (std::size_t r = 0; r < design.rods.size(); ++r) {
      const geometry::Rod& src = design.rods[r];
      rods.emplace_back(src.name(), src.centerline(), src.section(), src.referenceNormal(), src.orientation(), src.caps(),
                        field(r, modulus));
    }
    return rods;
  }
  void addCase(const mechanics::LoadCase& lc, const std::vector<geometry::Rod>& rods);
  mechanics::Solution solve(Case& c) const;
};

void DesignProblem::Impl::addCase(const mechanics::LoadCase& lc, const std::vector<geometry::Rod>& rods) {
  Case c;
  c.name = lc.name, c.path = lc.path, c.weight = lc.weight, c.loadSteps = lc.loadSteps;
  c.structure = std::make_unique<mechanics::Design>(mechanics::loadCaseStructure(design, lc));
  c.structure->rods = rods;
  const mechanics::Discretization d = cases.empty() ? settings.discretization : cases.front().problem->discretization();
  try {
    c.problem = std::make_unique<mechanics::StaticProblem>(*c.structure, d);
  } catch (const mechanics::MechanicsError& e) {
    throw OptimizeError("load case \"" + c.name + "\" (" + c.path + "): " + e.what());
  }
  c.targets = detail::sampleTargets(design, lc.target, *c.problem, c.path);
  cases.push_back(std::move(c));
}

// Continuation in E: Newton from the case's previous solution, the load path when that fails.
mechanics::Solution DesignProblem::Impl::solve(Case& c) const {
  try {
    mechanics::Solution s = c.solved ? mechanics::solveFrom(*c.problem, c.state, settings.solver, c.loadSteps)
                                     : mechanics::solve(*c.problem, settings.solver, c.loadSteps);
    c.state = s.state;
    c.solved = true;
    return s;
  } catch (const mechanics::ConvergenceError& e) {
    throw OptimizeError("load case \"" + c.name + "\" (" + c.path + ") does not converge: " + e.what());
  } catch (const mechanics::MechanicsError& e) {
    throw OptimizeError("load case \"" + c.name + "\" (" + c.path + "): " + e.what());
  }
}

DesignProblem::DesignProblem(const mechanics::Design& design, const Settings& settings)
    : impl_(std::make_unique<Impl>()) {
  checkSettings(settings);
  Impl& m = *impl_;
  m.settings = settings;
  m.design = design;
  m.degree = std::min(settings.modulusDegree, settings.modulusControls - 1);
  if (design.rods.empty()) throw OptimizeError(design.source + ": rods: the design has no rods to optimize");
  std::size_t withTarget = 0;
  for (const mechanics::LoadCase& lc : design.mechanics.loadCases) withTarget += lc.target.empty() ? 0 : 1;
  if (withTarget == 0)
    throw OptimizeError(design.source + ": mechanics.load_cases: no load case with a \"target\" shape to optimize for");
  for (const geometry::Rod& rod : design.rods)
    m.knots.push_back(uniformKnots(m.degree, settings.modulusControls, rod.centerline().domainBegin(), rod.centerline().domainEnd()));
  const std::vector<geometry::Rod> rods = m.rodsWith(startingModulus());
  for (const mechanics::LoadCase& lc : design.mechanics.loadCases) {
    m.addCase(lc, rods);
    if (m.cases.size() == 1) requireMemory(design.source, *m.cases.front().problem, design.mechanics.loadCases.size());
  }
}

DesignProblem::~DesignProblem() = default;
DesignProblem::DesignProblem(DesignProblem&&) noexcept = default;
DesignProblem& DesignProblem::operator=(DesignProblem&&) noexcept = default;

const Settings& DesignProblem::settings() const { return impl_->settings; }
std::size_t DesignProblem::variableCount() const { return impl_->design.rods.size() * impl_->settings.modulusControls; }
std::size_t DesignProblem::caseCount() const { return impl_->cases.size(); }
std::size_t DesignProblem::rodCount() const { return impl_->design.rods.size(); }
std::size_t DesignProblem::unknownCount() const { return impl_->cases.front().problem->unknownCount(); }
const mechanics::StaticProblem& DesignProblem::caseProblem(std::size_t c) const { return *impl_->cases.at(c).problem; }
const Eigen::VectorXd& DesignProblem::state(std::size_t c) const { return impl_->cases.at(c).state; }

Eigen::VectorXd DesignProblem::startingModulus() const {
  const Impl& m = *impl_;
  const int n = m.settings.modulusControls, p = m.degree;
  Eigen::VectorXd e(static_cast<Eigen::Index>(variableCount()));
  for (std::size_t r = 0; r < m.design.rods.size(); ++r) {
    const geometry::BSplineField& own = m.design.rods[r].modulus();
    if (!own.isConstant() && own.degree() == p && own.knots() == m.knots[r]) {  // already in the basis (an optimized design)
      for (int k = 0; k < n; ++k)
        e[static_cast<Eigen::Index>(r * n + k)] = std::clamp(own.values()[k], m.settings.lowerMpa, m.settings.upperMpa);
      continue;
    }
    for (int k = 0; k < n; ++k) {
      double greville = 0;
      for (int i = 1; i <= p; ++i) greville += m.knots[r][k + i];
      const double value = m.design.rods[r].modulus().value(greville / p);
      e[static_cast<Eigen::Index>(r * n + k)] = std::clamp(value, m.settings.lowerMpa, m.settings.upperMpa);
    }
  }
  return e;
}

Evaluation DesignProblem::evaluate(const Eigen::VectorXd& modulus, bool gradient) {
  Impl& m = *impl_;
  if (static_cast<std::size_t>(modulus.size()) != variableCount() || !modulus.allFinite() || !(modulus.minCoeff() > 0))
    throw std::invalid_argument("DesignProblem::evaluate: " + std::to_string(variableCount()) + " positive finite values expected");
  Evaluation out;
  if (gradient) out.gradient = Eigen::VectorXd::Zero(modulus.size());
  std::vector<geometry::BSplineField> fields;
  for (std::size_t r = 0; r < m.design.rods.size(); ++r) fields.push_back(m.field(r, modulus));
  for (Impl::Case& c : m.cases) {
    for (std::size_t r = 0; r < fields.size(); ++r) c.problem->setModulus(r, fields[r]);
    const mechanics::Solution s = m.solve(c);
    out.newtonIterations += s.newtonIterations + s.chordIterations;
    CaseObjective co{c.name, c.weight, 0.0, 0.0};
    if (c.targets.empty()) {
      out.cases.push_back(co);
      continue;
    }
    const detail::ShapeTerms t =
        detail::shapeObjective(*c.problem, c.targets, c.state, m.settings.positionWeight, m.settings.curvatureWeight, gradient);
    co.position = c.weight * t.position, co.curvature = c.weight * t.curvature;
    out.objective += co.total();
    out.cases.push_back(co);
    if (!gradient || c.weight == 0) continue;
    // Adjoint: J^T lambda = dg/dx at the solution, then dg/dE = -lambda^T dF/dE.
    const Eigen::VectorXd lambda = s.tangent->solveTransposed(t.gradient);
    out.gradient -= c.weight * (c.problem->modulusJacobian(c.state, 1.0).transpose() * lambda);
  }
  return out;
}

namespace {

// Largest difference of centerline displacements between two discretizations of one design (4
// samples per span of the finer, `b`), and the largest displacement of `a`, both in mm.
std::pair<double, double> displacementDifference(const mechanics::Design& design, const mechanics::StaticProblem& a,
                                                 const Eigen::VectorXd& xa, const mechanics::StaticProblem& b,
                                                 const Eigen::VectorXd& xb) {
  double difference = 0, displacement = 0;
  for (std::size_t r = 0; r < design.rods.size(); ++r) {
    const geometry::NurbsCurve& curve = design.rods[r].centerline();
    const int designSpans = static_cast<int>(curve.breakpoints().size()) - 1;
    const int samples = 4 * b.discretization().perRod[r] * (b.discretization().degree > 0 ? 1 : designSpans);
    for (int i = 0; i <= samples; ++i) {
      const double u = curve.domainBegin() + (curve.domainEnd() - curve.domainBegin()) * i / samples;
      const Eigen::Vector3d da = a.position(xa, r, u) - a.position(a.referenceState(), r, u);
      const Eigen::Vector3d db = b.position(xb, r, u) - b.position(b.referenceState(), r, u);
      difference = std::max(difference, (da - db).norm());
      displacement = std::max(displacement, da.norm());
    }
  }
  return {difference, displacement};
}

}  // namespace

// The error of the optimizer's level from a solve with twice the spans: if errors fall by r per
// doubling, e = d + e / r, so e = d r / (r - 1), r = 2^(order - 2) as mechanics assumes before it
// has observed one (a quarter of the asymptotic rate). Comparing with the finer level rather than
// a coarser one (what mechanics::simulate does) measures the level itself: the coarser level's
// error is not that of the optimizer's, and its solve is the one that fails on stiff problems.
std::vector<CaseAccuracy> DesignProblem::accuracyAt(const Eigen::VectorXd& modulus, const std::function<void()>& poll) const {
  const Impl& m = *impl_;
  if (static_cast<std::size_t>(modulus.size()) != variableCount())
    throw std::invalid_argument("DesignProblem::accuracyAt: " + std::to_string(variableCount()) + " values expected");
  const std::vector<geometry::Rod> rods = m.rodsWith(modulus);
  std::vector<CaseAccuracy> out;
  for (const Impl::Case& c : m.cases) {
    if (poll) poll();
    mechanics::Design s = *c.structure;
    s.rods = rods;
    mechanics::ErrorEstimate e;
    std::optional<mechanics::Stability> stability;
    std::vector<mechanics::CriticalPoint> criticalPoints;
    // The spans were chosen for the starting E(s): a steeper optimum may need more (told, not refined).
    const mechanics::StaticProblem kept(s, c.problem->discretization());
    const std::optional<mechanics::UnderResolvedRod> underResolved = kept.leastResolvedRod();
    try {
      const mechanics::Solution sol = mechanics::solve(kept, m.settings.solver, c.loadSteps,
                                                       [&](const mechanics::LoadStepReport&, const Eigen::VectorXd&) { if (poll) poll(); });
      stability = sol.stability, criticalPoints = sol.criticalPoints;
      mechanics::Discretization finer = c.problem->discretization();
      for (int& spans : finer.perRod) spans = std::min(2 * spans, mechanics::kMaxSpansPerRod);
      const mechanics::StaticProblem fine(s, finer);
      if (poll) poll();
      const mechanics::Solution f = mechanics::solveFrom(fine, fine.transferredState(kept, sol.state), m.settings.solver, c.loadSteps);
      const auto [difference, displacement] = displacementDifference(s, kept, sol.state, fine, f.state);
      const double ratio = std::max(2.0, std::ldexp(1.0, c.problem->convergenceOrder() - 2));
      e.available = true;
      e.positionError = difference * ratio / (ratio - 1.0);
      e.largestDisplacement = displacement;
      e.relative = e.positionError / std::max(displacement, 1e-6 * s.bounds().diagonal().norm());
      e.comparedUnknowns = fine.unknownCount();
    } catch (const mechanics::ConvergenceError& err) {
      e.available = false;
      e.note = std::string("a solve does not converge: ") + err.what();
    }
    out.push_back({c.name, e, underResolved, stability, std::move(criticalPoints)});
  }
  return out;
}

mechanics::Design DesignProblem::designWith(const Eigen::VectorXd& modulus) const {
  if (static_cast<std::size_t>(modulus.size()) != variableCount())
    throw std::invalid_argument("DesignProblem::designWith: " + std::to_string(variableCount()) + " values expected");
  mechanics::Design out = impl_->design;
  out.rods = impl_->rodsWith(modulus);
  return out;
}

std::optional<Start> parseStart(const std::string& text) {
  if (text == "design") return Start{};
  if (text == "uniform") return Start{true, 0.0};
  const std::string prefix = "uniform=";
  if (text.rfind(prefix, 0) != 0 || text.size() == prefix.size() || text.size() > prefix.size() + 32) return std::nullopt;
  // A decimal number only (strtod took 0x10 as 16 MPa): from_chars reads no hex, sign or blank.
  const std::string_view number = std::string_view(text).substr(prefix.size());
  double mpa = 0.0;
  const auto [end, error] = std::from_chars(number.data(), number.data() + number.size(), mpa);
  if (error != std::errc() || end != number.data() + number.size() || !std::isfinite(mpa) || !(mpa > 0)) return std::nullopt;
  return Start{true, mpa};
}

Eigen::VectorXd startingModulus(const DesignProblem& problem, const Start& start) {
  if (!start.uniform) return problem.startingModulus();
  const Settings& s = problem.settings();
  const double value = start.mpa > 0 ? start.mpa : std::clamp(std::sqrt(s.lowerMpa * s.upperMpa), s.lowerMpa, s.upperMpa);
  if (value < s.lowerMpa || value > s.upperMpa) {
    using common::exactNumber;
    throw OptimizeError("--start uniform=" + exactNumber(value) + ": outside the bounds [" + exactNumber(s.lowerMpa) + ", " +
                        exactNumber(s.upperMpa) + "] MPa");
  }
  return Eigen::VectorXd::Constant(static_cast<Eigen::Index>(problem.variableCount()), value);
}

mechanics::Design optimizedDesign(const DesignProblem& problem, const Eigen::VectorXd& modulus, const mechanics::Design& design,
                                  const std::filesystem::path& designFile, const std::filesystem::path& outputFile) {
  namespace fs = std::filesystem;
  mechanics::Design out = problem.designWith(modulus);
  const fs::path outputFolder = fs::absolute(outputFile).parent_path();
  for (mechanics::LoadCase& lc : out.mechanics.loadCases)
    if (!lc.targetDesign.empty() && !fs::path(lc.targetDesign).is_absolute())
      lc.targetDesign =
          mechanics::targetDesignFile(lc, fs::absolute(designFile)).lexically_normal().lexically_relative(outputFolder).string();
  out.optimize = design.optimize;
  return out;
}

}  // namespace rodfab::optimize
