// optimize/: the modulus derivative of the residual, the adjoint gradient against finite
// differences, and the optimizer on manufactured problems whose exact answer is known.
#include "optimize/optimize.hpp"

#include "calibration/calibration.hpp"
#include "geometry/geometry.hpp"
#include "materials/fraction_map.hpp"
#include "voxel/printer_grid.hpp"
#include "voxel/rasterize.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <random>

using namespace rodfab;
using mechanics::RodEnd;
using mechanics::Design;
using geometry::Vec3;

namespace {

geometry::NurbsCurve straight(const Vec3& a, const Vec3& b) {
  std::vector<Vec3> pts;
  for (int i = 0; i < 4; ++i) pts.push_back(a + (b - a) * (i / 3.0));
  return geometry::NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1, 1}, pts);
}

// A quarter arc of radius R in the plane z = h, centred on the z axis, degree 2 rational.
geometry::NurbsCurve arc(double R, double h) {
  const double w = std::sqrt(0.5);
  return geometry::NurbsCurve(2, {0, 0, 0, 1, 1, 1}, {Vec3(R, 0, h), Vec3(R, R, h), Vec3(0, R, h)}, {1.0, w, 1.0});
}

geometry::Rod rod(const std::string& name, geometry::NurbsCurve c, double d, double E) {
  const double a = c.domainBegin(), b = c.domainEnd();
  return geometry::Rod(name, std::move(c), geometry::Section::circle(d), std::nullopt, std::nullopt,
                       geometry::CapStyle::Round, geometry::BSplineField::constant(E, a, b));
}

mechanics::RodEndRef end(const std::string& name, RodEnd which) {
  mechanics::RodEndRef r;
  r.rod = name, r.end = which, r.path = "test";
  return r;
}

mechanics::PointLoad load(const std::string& name, const Vec3& force, const Vec3& moment) {
  mechanics::PointLoad l;
  l.at = end(name, RodEnd::End), l.force = force, l.moment = moment;
  return l;
}

// A clamped post, an arc joined rigidly to its top and a straight arm hanging from the arc's end:
// three rods, two joints, bending and torsion everywhere. Two load cases at the arm's free end.
// With `tJoint`, a loaded strut starts at the post's mid-height: a T-joint, the post's interior site.
// With `follower`, every load turns with its section (follower loads).
Design frame(bool tJoint = false, bool follower = false) {
  Design s;
  s.source = "frame";
  s.rods.push_back(rod("post", straight(Vec3(40, 0, 0), Vec3(40, 0, 60)), 4.0, 60.0));
  s.rods.push_back(rod("arc", arc(40, 60), 3.5, 60.0));
  s.rods.push_back(rod("arm", straight(Vec3(0, 40, 60), Vec3(0, 40, 20)), 3.0, 60.0));
  if (tJoint) s.rods.push_back(rod("strut", straight(Vec3(40, 0, 30), Vec3(60, 0, 30)), 2.5, 60.0));
  s.mechanics.present = true;
  mechanics::Support clamp;
  clamp.at = end("post", RodEnd::Start);
  mechanics::LoadCase push, twist;
  push.name = "push", push.path = "mechanics.load_cases[0]", push.loadSteps = 4;
  push.supports = {clamp};
  push.loads = {load("arm", Vec3(0.3, 0.0, -0.1), Vec3::Zero())};
  twist.name = "twist", twist.path = "mechanics.load_cases[1]", twist.loadSteps = 4, twist.weight = 0.5;
  twist.supports = {clamp};
  twist.loads = {load("arm", Vec3(0.0, -0.2, 0.0), Vec3(4.0, 0.0, 3.0))};
  if (tJoint)
    for (mechanics::LoadCase* c : {&push, &twist}) c->loads.push_back(load("strut", Vec3(0.0, 0.05, -0.05), Vec3::Zero()));
  for (mechanics::LoadCase* c : {&push, &twist})
    for (mechanics::PointLoad& l : c->loads) l.follower = follower;
  s.mechanics.loadCases = {push, twist};
  s.mechanics.supports = {clamp};
  return s;
}

// Every case's target: the shapes `problem` reached at its last evaluation.
void setTargetsFromStates(Design& design, const optimize::DesignProblem& problem) {
  for (std::size_t c = 0; c < problem.caseCount(); ++c) {
    const Design deformed = problem.caseProblem(c).deformedStructure(problem.state(c));
    auto& target = design.mechanics.loadCases[c].target;
    target.clear();
    for (const geometry::Rod& r : deformed.rods)
      target.push_back({r.name(), r.centerline(), r.orientation(), std::nullopt, "test"});
  }
}

Eigen::VectorXd randomModulus(std::size_t n, double lo, double hi, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  Eigen::VectorXd e(static_cast<Eigen::Index>(n));
  for (auto& v : e) v = u(rng);
  return e;
}

// The frame with targets: the shapes of a random modulus field between the bounds.
Design manufactured(const optimize::Settings& settings, unsigned seed, Eigen::VectorXd* truth = nullptr,
                    bool tJoint = false, bool follower = false) {
  Design design = frame(tJoint, follower);
  for (auto& lc : design.mechanics.loadCases) lc.target.push_back({"post", straight(Vec3(40, 0, 0), Vec3(40, 0, 60)), std::nullopt, std::nullopt, "t"});
  optimize::DesignProblem generator(design, settings);
  const Eigen::VectorXd e = randomModulus(generator.variableCount(), settings.lowerMpa, settings.upperMpa, seed);
  generator.evaluate(e, false);
  setTargetsFromStates(design, generator);
  if (truth) *truth = e;
  return design;
}

optimize::Settings testSettings() {
  optimize::Settings s;
  s.solver.tolerance = 1e-12;
  s.solver.chordSteps = false;  // every correction full Newton: solutions to rounding for the difference quotients
  return s;
}

}  // namespace

TEST_CASE("dF/dE matches central differences of the residual at an equilibrium", "[optimize]") {
  const optimize::Settings settings = testSettings();
  const bool tJoint = GENERATE(false, true);
  INFO((tJoint ? "with" : "without") << " a T-joint");
  optimize::DesignProblem problem(manufactured(settings, 7, nullptr, tJoint), settings);
  const Eigen::VectorXd e = randomModulus(problem.variableCount(), 20, 150, 3);
  problem.evaluate(e, false);
  // A copy of the problem to perturb: the same discretization, rebuilt.
  optimize::DesignProblem copy(manufactured(settings, 7, nullptr, tJoint), settings);
  copy.evaluate(e, false);
  const mechanics::StaticProblem& sp = problem.caseProblem(1);
  const Eigen::VectorXd& x = problem.state(1);
  const Eigen::SparseMatrix<double> dFdE = sp.modulusJacobian(x, 1.0);
  REQUIRE(dFdE.cols() == static_cast<Eigen::Index>(problem.variableCount()));
  REQUIRE(sp.modulusVariableCount() == problem.variableCount());
  auto& perturbed = const_cast<mechanics::StaticProblem&>(copy.caseProblem(1));
  const int n = settings.modulusControls;
  double worst = 0, largest = 0;
  const Design withE = copy.designWith(e);
  for (Eigen::Index k = 0; k < dFdE.cols(); ++k) {
    const std::size_t rodIndex = static_cast<std::size_t>(k) / n;
    const geometry::Rod& r = withE.rods[rodIndex];
    Eigen::VectorXd fPlus, fMinus;
    for (int sign : {1, -1}) {
      std::vector<double> values = r.modulus().values();
      values[k % n] += sign * 1e-3;
      perturbed.setModulus(rodIndex, geometry::BSplineField(r.modulus().degree(), r.modulus().knots(), values));
      perturbed.evaluate(x, 1.0, sign > 0 ? fPlus : fMinus);
    }
    perturbed.setModulus(rodIndex, r.modulus());
    const Eigen::VectorXd fd = (fPlus - fMinus) / 2e-3;
    const Eigen::VectorXd exact = dFdE.col(k);
    worst = std::max(worst, (fd - exact).lpNorm<Eigen::Infinity>());
    largest = std::max(largest, exact.lpNorm<Eigen::Infinity>());
  }
  INFO("largest entry " << largest << ", largest difference " << worst);
  CHECK(largest > 0);
  CHECK(worst <= 1e-7 * largest);
}

TEST_CASE("the adjoint gradient matches central finite differences (joints, a T-joint, two cases, both terms)", "[optimize]") {
  optimize::Settings settings = testSettings();
  settings.curvatureWeight = 3.0;
  const bool tJoint = GENERATE(false, true);
  const bool follower = GENERATE(false, true);  // follower loads: their q-derivative is in the adjoint's Jacobian
  INFO((tJoint ? "with" : "without") << " a T-joint, " << (follower ? "follower" : "dead") << " loads");
  optimize::DesignProblem problem(manufactured(settings, 11, nullptr, tJoint, follower), settings);
  REQUIRE(problem.caseCount() == 2);
  const Eigen::VectorXd e = randomModulus(problem.variableCount(), 20, 150, 5);
  const optimize::Evaluation ev = problem.evaluate(e, true);
  REQUIRE(ev.cases.size() == 2);
  CHECK(ev.cases[0].position > 0);
  CHECK(ev.cases[1].curvature > 0);
  // Fourth-order central differences: truncation and solver noise both well below 1e-6.
  const auto g = [&](Eigen::VectorXd v) { return problem.evaluate(v, false).objective; };
  Eigen::VectorXd fd(e.size());
  for (Eigen::Index k = 0; k < e.size(); ++k) {
    const double h = 1e-3 * e[k];
    const auto at = [&](double t) { Eigen::VectorXd v = e; v[k] += t; return g(v); };
    fd[k] = (8 * (at(h) - at(-h)) - (at(2 * h) - at(-2 * h))) / (12 * h);
  }
  const double error = (fd - ev.gradient).norm() / ev.gradient.norm();
  INFO("gradient " << ev.gradient.transpose() << "\nfinite differences " << fd.transpose() << "\nrelative error " << error);
  CHECK(error <= 1e-6);
}

TEST_CASE("targets made from the design's own solved shapes score nothing at its modulus, T-joints included", "[optimize]") {
  // The strut's T-joint on the post carries a point force and moment: the post's curvature jumps
  // there. The target's curvature was a central difference across the jump and the state's from
  // above it: g at the true E was 0.2 of g0, and optimizing from a uniform E stopped at g/g0 0.58.
  const optimize::Settings settings = testSettings();
  const bool tJoint = GENERATE(false, true);
  INFO((tJoint ? "with" : "without") << " a T-joint");
  Eigen::VectorXd truth;
  optimize::DesignProblem problem(manufactured(settings, 7, &truth, tJoint), settings);
  const double g0 = problem.evaluate(problem.startingModulus(), false).objective;
  const optimize::Evaluation atTruth = problem.evaluate(truth, false);
  for (const optimize::CaseObjective& c : atTruth.cases) {
    INFO("case " << c.name << ": position " << c.position << ", curvature " << c.curvature << ", g0 " << g0);
    CHECK(c.position < 1e-10 * g0);
    CHECK(c.curvature < 1e-8 * g0);
  }
}

TEST_CASE("a manufactured problem: from a uniform modulus to g / g0 <= 1e-6 within the bounds", "[optimize]") {
  optimize::Settings settings = testSettings();
  settings.scaling = GENERATE(optimize::Scaling::Linear, optimize::Scaling::Logarithmic);
  INFO((settings.scaling == optimize::Scaling::Linear ? "linear" : "logarithmic") << " scaling");
  settings.objectiveTolerance = 1e-7;
  settings.maxIterations = 400;
  Eigen::VectorXd truth;
  optimize::DesignProblem problem(manufactured(settings, 21, &truth), settings);
  const Eigen::VectorXd start = problem.startingModulus();
  CHECK(start.minCoeff() == Approx(60.0));
  CHECK(start.maxCoeff() == Approx(60.0));
  int reports = 0;
  const optimize::Result result = optimize::optimize(problem, [&](const optimize::Iteration&) { ++reports; });
  const double relative = result.final.objective / result.initial.objective;
  INFO(problem.rodCount() << " rods, " << problem.unknownCount() << " unknowns per case, " << problem.variableCount()
                          << " design variables, " << result.seconds << " s");
  INFO("g0 " << result.initial.objective << ", g " << result.final.objective << " (g/g0 " << relative << ") after "
             << result.iterations << " iterations, " << result.evaluations << " evaluations: " << result.stopReason
             << "\nE " << result.modulus.transpose() << "\ntruth " << truth.transpose());
  CHECK(relative <= 1e-6);
  CHECK(reports == result.iterations + 1);
  CHECK(result.modulus.minCoeff() >= settings.lowerMpa);
  CHECK(result.modulus.maxCoeff() <= settings.upperMpa);
}

TEST_CASE("NLopt's MMA and CCSAQ on the manufactured problem: g falls, one report per evaluation, bounds kept", "[optimize]") {
  optimize::Settings settings = testSettings();
  settings.method = GENERATE(optimize::Method::Mma, optimize::Method::Ccsaq);
  INFO((settings.method == optimize::Method::Mma ? "MMA" : "CCSAQ"));
  settings.maxIterations = 60;
  optimize::DesignProblem problem(manufactured(settings, 21, nullptr, false, true), settings);
  int reports = 0;
  const optimize::Result result = optimize::optimize(problem, [&](const optimize::Iteration&) { ++reports; });
  const double relative = result.final.objective / result.initial.objective;
  INFO("g/g0 " << relative << " after " << result.iterations << " iterations: " << result.stopReason);
  CHECK(relative <= 1e-2);
  CHECK(result.evaluations == result.iterations + 1);  // the start is evaluated once
  CHECK(reports == result.iterations + 1);
  CHECK(result.iterations <= settings.maxIterations);
  CHECK(result.modulus.minCoeff() >= settings.lowerMpa);
  CHECK(result.modulus.maxCoeff() <= settings.upperMpa);
  // The states belong to the best point.
  CHECK(problem.evaluate(result.modulus, false).objective == Approx(result.final.objective).epsilon(1e-9));
}

TEST_CASE("The start (--start): the design's modulus, or one modulus everywhere within the bounds", "[optimize]") {
  CHECK_FALSE(optimize::parseStart("design")->uniform);
  CHECK(optimize::parseStart("uniform")->uniform);
  CHECK(optimize::parseStart("uniform")->mpa == 0.0);
  CHECK(optimize::parseStart("uniform=42.5")->mpa == 42.5);
  for (const char* bad : {"", "flat", "uniform=", "uniform=0", "uniform=-1", "uniform=nan", "uniform=inf", "uniform=12x", "uniform=1e999",
                          "uniform=0x10", "uniform= 12"})
    CHECK_FALSE(optimize::parseStart(bad));
  const optimize::Settings settings = testSettings();
  optimize::DesignProblem problem(manufactured(settings, 3), settings);
  const Eigen::VectorXd mean = optimize::startingModulus(problem, *optimize::parseStart("uniform"));
  CHECK(mean.size() == static_cast<Eigen::Index>(problem.variableCount()));
  CHECK(mean.minCoeff() == Approx(std::sqrt(8.0 * 190.0)));
  CHECK(mean.maxCoeff() == mean.minCoeff());
  CHECK(optimize::startingModulus(problem, *optimize::parseStart("uniform=150"))[0] == 150.0);
  CHECK(optimize::startingModulus(problem, *optimize::parseStart("design")) == problem.startingModulus());
  CHECK_THROWS_WITH(optimize::startingModulus(problem, *optimize::parseStart("uniform=7")),
                    Catch::Contains("--start uniform=7: outside the bounds [8, 190] MPa"));
}

TEST_CASE("a target only reachable beyond the bounds ends on them, a stationary point of the bounded problem", "[optimize]") {
  optimize::Settings settings = testSettings();
  settings.maxIterations = 100;
  settings.lowerMpa = 8.0, settings.upperMpa = 190.0;
  // The shapes of a structure stiffer than the upper bound allows everywhere.
  optimize::Settings wide = settings;
  wide.upperMpa = 1000.0;
  Design design = frame();
  for (auto& lc : design.mechanics.loadCases) lc.target.push_back({"post", straight(Vec3(40, 0, 0), Vec3(40, 0, 60)), std::nullopt, std::nullopt, "t"});
  optimize::DesignProblem generator(design, wide);
  generator.evaluate(Eigen::VectorXd::Constant(static_cast<Eigen::Index>(generator.variableCount()), 400.0), false);
  setTargetsFromStates(design, generator);
  optimize::DesignProblem problem(design, settings);
  const optimize::Result result = optimize::optimize(problem);
  INFO("E " << result.modulus.transpose() << "\n" << result.stopReason);
  CHECK(result.modulus.minCoeff() >= settings.lowerMpa);
  CHECK(result.modulus.maxCoeff() <= settings.upperMpa);
  // The rods the load bends are as stiff as allowed.
  CHECK(result.modulus.maxCoeff() == settings.upperMpa);
}

TEST_CASE("an optimum on the lower bound is the bound to the last bit (exp(log 8) is not 8)", "[optimize]") {
  optimize::Settings settings = testSettings();
  settings.scaling = GENERATE(optimize::Scaling::Linear, optimize::Scaling::Logarithmic);
  settings.maxIterations = 100;
  // The shapes of a structure softer than the lower bound allows everywhere.
  optimize::Settings wide = settings;
  wide.lowerMpa = 1.0;
  Design design = frame();
  for (auto& lc : design.mechanics.loadCases) lc.target.push_back({"post", straight(Vec3(40, 0, 0), Vec3(40, 0, 60)), std::nullopt, std::nullopt, "t"});
  optimize::DesignProblem generator(design, wide);
  generator.evaluate(Eigen::VectorXd::Constant(static_cast<Eigen::Index>(generator.variableCount()), 7.0), false);
  setTargetsFromStates(design, generator);
  optimize::DesignProblem problem(design, settings);
  const optimize::Result result = optimize::optimize(problem);
  INFO("E " << result.modulus.transpose() << "\n" << result.stopReason);
  CHECK(result.modulus.minCoeff() == settings.lowerMpa);
  CHECK(result.modulus.maxCoeff() <= settings.upperMpa);
  CHECK(result.final.objective < result.initial.objective);
  CHECK(result.history.back().projectedGradient < 1e-3);
}

TEST_CASE("an optimum on both bounds prints without a clamped voxel (issue 16)", "[optimize][slice]") {
  openvdb::initialize();
  optimize::Settings settings = testSettings();
  settings.maxIterations = 100;
  // Targets only reachable with E beyond both bounds along each rod: the optimum sits on them, and
  // E(u) of each rod runs from one bound to the other (where a voxel's interpolated E could step past).
  optimize::Settings wide = settings;
  wide.lowerMpa = 1.0, wide.upperMpa = 1000.0;
  Design design = frame();
  for (auto& lc : design.mechanics.loadCases) lc.target.push_back({"post", straight(Vec3(40, 0, 0), Vec3(40, 0, 60)), std::nullopt, std::nullopt, "t"});
  optimize::DesignProblem generator(design, wide);
  Eigen::VectorXd beyond(static_cast<Eigen::Index>(generator.variableCount()));
  for (Eigen::Index k = 0; k < beyond.size(); ++k) beyond[k] = (k / 2) % 2 ? 3.0 : 600.0;
  generator.evaluate(beyond, false);
  setTargetsFromStates(design, generator);
  optimize::DesignProblem problem(design, settings);
  const optimize::Result result = optimize::optimize(problem);
  INFO("E " << result.modulus.transpose() << "\n" << result.stopReason);
  REQUIRE(result.modulus.minCoeff() == settings.lowerMpa);
  REQUIRE(result.modulus.maxCoeff() == settings.upperMpa);

  // Sliced as `rodfab slice` does: rasterized, then mapped through a calibration whose floor and
  // stiffest mix are the bounds (the bundled 60 C fit's nodes).
  calibration::ModelParameters fit;
  fit.fractions = {0.0, 0.3, 1.0};
  fit.moduliMpa = {0.5, 8.0, 190.0};
  const calibration::Calibration cal(fit, 8.0);
  const geometry::RodStructure optimized = problem.designWith(result.modulus);
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(optimized, openvdb::Vec3d(0.2, 0.2, 0.2));
  const voxel::Rasterization ras = voxel::rasterize(optimized, grid);
  float low = 1e30f, high = -1e30f;
  for (auto it = ras.grid->cbeginValueOn(); it; ++it) low = std::min(low, *it), high = std::max(high, *it);
  INFO("voxel E in [" << low << ", " << high << "]");
  CHECK(low == 8.0f);  // the voxels do reach both bounds
  CHECK(high == 190.0f);
  materials::MappingStats stats;
  materials::mapToFractions(*ras.grid, materials::FractionMap(cal), stats);
  CHECK(stats.voxels > 100000);
  CHECK(stats.clamps.belowFloor == 0);
  CHECK(stats.clamps.aboveMax == 0);
}

TEST_CASE("an optimized design resumes from its own control values, drawn shapes are the solved states", "[optimize]") {
  const optimize::Settings settings = testSettings();
  optimize::DesignProblem problem(manufactured(settings, 7), settings);
  const Eigen::VectorXd e = randomModulus(problem.variableCount(), 20, 150, 9);
  optimize::DesignProblem again(problem.designWith(e), settings);
  CHECK((again.startingModulus() - e).lpNorm<Eigen::Infinity>() == 0.0);
  problem.evaluate(e, false);
  const std::vector<optimize::DrawnRod> drawn = optimize::drawnDeformed(problem, 1, e, 8);
  REQUIRE(drawn.size() == problem.rodCount());
  // The arm's free end as the deformed design (mechanics' own output) has it; E as the design has it.
  const Design deformed = problem.caseProblem(1).deformedStructure(problem.state(1));
  const geometry::NurbsCurve& arm = deformed.rods[2].centerline();
  CHECK((drawn[2].points.back() - arm.point(arm.domainEnd())).norm() < 1e-9);
  CHECK((drawn[0].points.front() - Vec3(40, 0, 0)).norm() < 1e-9);  // the clamped foot
  const Design withE = problem.designWith(e);
  CHECK(drawn[1].modulusMpa[4] == Approx(withE.rods[1].modulus().value(0.5)));
  const std::vector<optimize::DrawnRod> target = optimize::drawnTarget(manufactured(settings, 7).mechanics.loadCases[0].target, 8);
  REQUIRE(target.size() == 3);
  CHECK(target[0].points.size() == 9);
  CHECK(target[0].modulusMpa.empty());
}

TEST_CASE("the accuracy at the optimum: the error estimate is the size of the difference from a finer solve", "[optimize]") {
  const optimize::Settings settings = testSettings();
  const Design design = manufactured(settings, 7);
  optimize::DesignProblem problem(design, settings);
  const Eigen::VectorXd e = randomModulus(problem.variableCount(), 20, 150, 13);
  problem.evaluate(e, false);
  const std::vector<optimize::CaseAccuracy> accuracy = problem.accuracyAt(e);
  REQUIRE(accuracy.size() == 2);
  for (std::size_t c = 0; c < 2; ++c) {
    const mechanics::ErrorEstimate& est = accuracy[c].estimate;
    INFO("case " << accuracy[c].name << ": " << est.note);
    REQUIRE(est.available);
    CHECK_FALSE(accuracy[c].underResolved);  // the automatic spans, for a moderate E(s)
    CHECK(accuracy[c].stability == mechanics::Stability::Stable);  // the load path at the optimum
    CHECK(accuracy[c].criticalPoints.empty());
    // The truth: the same case with four times the spans.
    Design s = problem.designWith(e);
    const mechanics::LoadCase& lc = design.mechanics.loadCases[c];
    s.mechanics.supports = lc.supports, s.mechanics.loads = lc.loads, s.mechanics.loadCases.clear();
    mechanics::Discretization fine = problem.caseProblem(c).discretization();
    for (int& spans : fine.perRod) spans *= 4;
    mechanics::AccuracyOptions once;
    once.estimate = false;
    const mechanics::Simulation ref = mechanics::simulate(s, fine, settings.solver, lc.loadSteps, once);
    double truth = 0;
    for (std::size_t r = 0; r < problem.rodCount(); ++r)
      for (double u : {0.0, 0.25, 0.5, 0.75, 1.0})
        truth = std::max(truth, (ref.problem->position(ref.solution.state, r, u) -
                                 problem.caseProblem(c).position(problem.state(c), r, u)).norm());
    INFO("estimated " << est.positionError << " mm, difference from the finer solve " << truth << " mm");
    CHECK(est.positionError > 0.8 * truth);
    CHECK(est.positionError < 1.5 * truth);
  }
}

TEST_CASE("the load path at the optimum: a case pushed past buckling says so", "[optimize]") {
  // A 60 mm post of 1 mm, clamped at its foot, pushed down its axis with twice its Euler load at 60 MPa
  // (two modes at once: a round section), its target the straight post. The optimizer's solves
  // continue from the previous E(s) and see no critical point; accuracyAt's load path does.
  const double L = 60, E = 60, I = std::numbers::pi / 64, critical = std::numbers::pi * std::numbers::pi * E * I / (4 * L * L);
  Design design;
  design.source = "column";
  design.rods.push_back(rod("post", straight(Vec3::Zero(), Vec3(0, 0, L)), 1.0, E));
  design.mechanics.present = true;
  mechanics::Support clamp;
  clamp.at = end("post", RodEnd::Start);
  mechanics::LoadCase push;
  push.name = "push", push.path = "mechanics.load_cases[0]", push.loadSteps = 10;
  push.supports = {clamp};
  push.loads = {load("post", Vec3(0, 0, -2 * critical), Vec3::Zero())};
  push.target.push_back({"post", straight(Vec3::Zero(), Vec3(0, 0, L)), std::nullopt, std::nullopt, "t"});
  design.mechanics.loadCases = {push};
  design.mechanics.supports = {clamp};
  optimize::DesignProblem problem(design, testSettings());
  const Eigen::VectorXd uniform = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(problem.variableCount()), E);
  const std::vector<optimize::CaseAccuracy> accuracy = problem.accuracyAt(uniform);
  REQUIRE(accuracy.size() == 1);
  CHECK(accuracy[0].stability == mechanics::Stability::Unstable);
  REQUIRE(accuracy[0].criticalPoints.size() == 1);
  const mechanics::CriticalPoint& c = accuracy[0].criticalPoints[0];
  INFO("bracket [" << c.fromLoad << ", " << c.toLoad << "]");
  CHECK(c.fromLoad <= 0.5 + 2e-4);
  CHECK(c.toLoad >= 0.5 - 2e-4);
}

TEST_CASE("an optimum graded more steeply than the start is told when the kept spans fall short of it", "[optimize]") {
  // The spans are chosen once, for the starting E(s); E alternating between 8 and 190 MPa from one
  // control value to the next falls by its own size over a few tenths of a mm, for which the a
  // priori model (mechanics/README.md) asks for more spans than the start's.
  const optimize::Settings settings = testSettings();
  optimize::DesignProblem problem(manufactured(settings, 7), settings);
  Eigen::VectorXd steep(problem.variableCount());
  for (Eigen::Index i = 0; i < steep.size(); ++i) steep[i] = i % 2 == 0 ? 8.0 : 190.0;
  const std::vector<optimize::CaseAccuracy> accuracy = problem.accuracyAt(steep);
  for (const optimize::CaseAccuracy& a : accuracy) {
    INFO("case " << a.name);
    REQUIRE(a.underResolved);
    CHECK(a.underResolved->spans < a.underResolved->needed);
    CHECK(a.underResolved->degree == 6);
  }
}
