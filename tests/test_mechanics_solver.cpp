// mechanics/: the sparse LU, the load path (steps, stability) and mechanisms.
#include "mechanics/mechanics.hpp"
#include "mechanics/section_properties.hpp"
#include "tests/mechanics_fixture.hpp"

#include "geometry/geometry.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <random>

using namespace rodfab;
using geometry::Section;
using geometry::Vec3;
using mechanics::Design;
using mechanics::StaticProblem;
using test::arc;
using test::at;
using test::atParameter;
using test::cantilever;
using test::clamp;
using test::kPi;
using test::straight;
using test::tip;

// ---- Sparse LU -----------------------------------------------------------------------------------

namespace {

// A random sparse 49 x 49 matrix in 7 x 7 blocks: dense diagonal blocks with zeros on their
// diagonal (as the collocation Jacobian has) and a few off-diagonal blocks.
Eigen::SparseMatrix<double> blockMatrix(std::mt19937& rng) {
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  std::vector<Eigen::Triplet<double>> entries;
  for (int b = 0; b < 7; ++b)
    for (int r = 0; r < 7; ++r)
      for (int c = 0; c < 7; ++c) {
        if (r == c && r % 2 == 0) continue;  // a structurally zero diagonal entry in every other row
        entries.emplace_back(7 * b + r, 7 * b + c, value(rng));
        if (b > 0 && (r + c) % 3 == 0) entries.emplace_back(7 * b + r, 7 * (b - 1) + c, 0.3 * value(rng));
        if (b + 1 < 7 && (r * c) % 5 == 1) entries.emplace_back(7 * b + r, 7 * (b + 1) + c, 0.3 * value(rng));
      }
  Eigen::SparseMatrix<double> m(49, 49);
  m.setFromTriplets(entries.begin(), entries.end());
  m.makeCompressed();
  return m;
}

}  // namespace

TEST_CASE("JacobianLU solves, solves transposed and gives the determinant's sign, against a dense LU", "[mechanics]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  mechanics::JacobianLU lu(7);
  Eigen::SparseMatrix<double> m = blockMatrix(rng);
  for (int round = 0; round < 4; ++round) {
    // Same pattern, new values: the later rounds refactorize along the first pivots.
    if (round > 0)
      for (Eigen::Index i = 0; i < m.nonZeros(); ++i) m.valuePtr()[i] *= 1.0 + 0.2 * value(rng);
    REQUIRE(lu.factorize(m));
    const Eigen::MatrixXd dense(m);
    const Eigen::PartialPivLU<Eigen::MatrixXd> reference(dense);
    Eigen::VectorXd b(49);
    for (Eigen::Index i = 0; i < b.size(); ++i) b[i] = value(rng);
    INFO("round " << round);
    CHECK((lu.solve(b) - reference.solve(b)).norm() < 1e-10 * reference.solve(b).norm());
    const Eigen::VectorXd y = lu.solveTransposed(b);
    CHECK((dense.transpose() * y - b).norm() < 1e-10 * b.norm());
    CHECK(lu.determinantSign() == (reference.determinant() > 0 ? 1 : -1));
    // ln |det J| from KLU's scaled factors against the dense LU's diagonal.
    CHECK(lu.logAbsDeterminant() == Approx(reference.matrixLU().diagonal().cwiseAbs().array().log().sum()).epsilon(1e-10));
  }
  CHECK(lu.analyses() == 1);
  CHECK(lu.refactorizations() + lu.factorizations() == 4);
  // Flipping one row flips the sign.
  Eigen::SparseMatrix<double> flipped = m;
  for (int c = 0; c < flipped.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(flipped, c); it; ++it)
      if (it.row() == 3) it.valueRef() = -it.value();
  const int before = lu.determinantSign();
  REQUIRE(lu.factorize(flipped, mechanics::JacobianLU::Pivoting::Fresh));
  CHECK(lu.determinantSign() == -before);
}

TEST_CASE("JacobianLU reports a singular matrix and refuses bad input", "[mechanics]") {
  std::mt19937 rng(5);
  Eigen::SparseMatrix<double> m = blockMatrix(rng);
  for (int c = 0; c < m.outerSize(); ++c)  // row 10 := row 9: singular
    for (Eigen::SparseMatrix<double>::InnerIterator it(m, c); it; ++it)
      if (it.row() == 10) it.valueRef() = 0.0;
  mechanics::JacobianLU lu(7);
  CHECK_FALSE(lu.factorize(m));
  CHECK_THROWS_AS(lu.solve(Eigen::VectorXd::Ones(49)), std::logic_error);
  CHECK_THROWS_AS(lu.factorize(Eigen::SparseMatrix<double>(3, 4)), std::invalid_argument);
  Eigen::SparseMatrix<double> bad = blockMatrix(rng);
  bad.valuePtr()[5] = std::numeric_limits<double>::quiet_NaN();
  CHECK_FALSE(lu.factorize(bad));
}

// ---- Load path, stability ------------------------------------------------------------------------

namespace {

// A 100 x 10 x 1 mm strip clamped at one end, loaded at the other in the plane of its height:
// lateral-torsional buckling at P = 4.0126 sqrt(EI GJ) / L^2 (Timoshenko & Gere; EI about the weak
// axis), raised by 1 / sqrt((1 - EIw / EIs) (1 - GJ / EIs)) = 1.012 for the in-plane deflection
// before buckling.
struct Strip {
  Design design;
  double critical;  // N
};

Strip strip(double loadFactor) {
  const double L = 100, E = 1000, nu = 0.3;
  const Section section = Section::rectangle(10, 1);  // 10 along d1 = z, 1 along d2
  const auto props = mechanics::sectionProperties(section, nu);
  const double EIweak = E * props.inertia1, EIstrong = E * props.inertia2, GJ = E / (2 * (1 + nu)) * props.torsionConstant;
  const double critical = 4.0126 * std::sqrt(EIweak * GJ) / (L * L) / std::sqrt((1 - EIweak / EIstrong) * (1 - GJ / EIstrong));
  Design s = cantilever(straight(Vec3::Zero(), Vec3(L, 0, 0), 1, 2), section, E, Vec3(0, 0, -loadFactor * critical),
                              Vec3::Zero(), Vec3(0, 0, 1));
  s.mechanics.poissonRatio = nu;
  return {s, critical};
}

}  // namespace

TEST_CASE("a strip below its lateral-torsional buckling load is stable, above it unstable", "[mechanics]") {
  mechanics::SolverOptions options;
  options.loadSteps = 10;
  SECTION("at 0.9 of the critical load: stable, no critical point, no lateral deflection") {
    const Strip s = strip(0.9);
    const StaticProblem problem(s.design);
    const auto solution = mechanics::solve(problem, options, 10);
    CHECK(solution.stability == mechanics::Stability::Stable);
    CHECK(solution.criticalPoints.empty());
    for (const auto& step : solution.steps) CHECK(step.determinantSign == 1);
    CHECK(std::abs(tip(problem, solution.state).y()) < 1e-9);
  }
  SECTION("at 1.1 of it: the straight state is unstable; the bifurcation is found at the critical load") {
    const Strip s = strip(1.1);
    const StaticProblem problem(s.design);
    const auto solution = mechanics::solve(problem, options, 10);
    CHECK(solution.stability == mechanics::Stability::Unstable);
    REQUIRE(solution.criticalPoints.size() == 1);
    const auto& c = solution.criticalPoints[0];
    CHECK(c.kind == mechanics::CriticalPoint::Kind::Bifurcation);
    CHECK(c.loadAlignment < 1e-6);  // the lateral mode is orthogonal to the in-plane load by symmetry
    CHECK(c.toLoad - c.fromLoad <= 1e-3 + 1e-12);
    const double found = 0.5 * (c.fromLoad + c.toLoad) * 1.1;  // in units of the critical load
    INFO("critical load found at " << found << " of the closed form");
    CHECK(std::abs(found - 1) < 0.005);
    CHECK(solution.steps.back().determinantSign == -1);
    CHECK(std::abs(tip(problem, solution.state).y()) < 1e-9);  // still straight: the unstable branch
  }
  SECTION("at 1.1 with followStableBranch: the strip buckles sideways and is stable") {
    const Strip s = strip(1.1);
    const StaticProblem problem(s.design);
    options.followStableBranch = true;
    const auto solution = mechanics::solve(problem, options, 10);
    CHECK(solution.stability == mechanics::Stability::Stable);
    REQUIRE(solution.criticalPoints.size() == 1);
    CHECK(solution.criticalPoints[0].branchSwitched);
    const Vec3 t = tip(problem, solution.state);
    INFO("buckled tip " << t.transpose());
    CHECK(std::abs(t.y()) > 5.0);  // mm sideways
    // The residual is that of an equilibrium at load 1.
    Eigen::VectorXd residual;
    problem.evaluate(solution.state, 1.0, residual);
    CHECK(residual.lpNorm<Eigen::Infinity>() < 1e-8);
  }
}

TEST_CASE("an Euler column's bifurcation is bracketed where it is, whatever the load steps", "[mechanics]") {
  // Clamped-free, 50 mm, a 1 x 0.8 mm rectangle (weak axis about d2), E 100: Pcr = pi^2 EI / (4 L^2);
  // loaded by 1.3 Pcr the path crosses it at load factor 1 / 1.3 (shortening and shear move it by
  // under 2e-4). The sign of det J was read before Newton's last correction, a step late: brackets
  // [0.8, 0.8008] at 10 steps, [0.857, 0.858] at 7, none at 4.
  const double L = 50, E = 100, I = 1.0 * std::pow(0.8, 3) / 12, critical = kPi * kPi * E * I / (4 * L * L);
  const Design column = cantilever(straight(Vec3::Zero(), Vec3(L, 0, 0), 1, 2), Section::rectangle(1.0, 0.8), E,
                                   Vec3(-1.3 * critical, 0, 0), Vec3::Zero(), Vec3(0, 0, 1));
  const StaticProblem problem(column);
  for (const int steps : {4, 7, 10}) {
    INFO(steps << " load steps");
    mechanics::SolverOptions options;
    const auto solution = mechanics::solve(problem, options, steps);
    REQUIRE(solution.criticalPoints.size() == 1);
    const auto& c = solution.criticalPoints[0];
    CHECK(c.kind == mechanics::CriticalPoint::Kind::Bifurcation);
    CHECK(c.fromLoad <= 1 / 1.3 + 2e-4);
    CHECK(c.toLoad >= 1 / 1.3 - 2e-4);
    CHECK(solution.stability == mechanics::Stability::Unstable);
    // Each step's sign is that of its own state: negative from the first step past the critical load.
    for (const auto& step : solution.steps) CHECK(step.determinantSign == (step.loadFactor > 1 / 1.3 ? -1 : 1));
  }
  // Continued on the stable branch: the buckled elastica. lambda L = K(k) with lambda^2 = P / EI,
  // tip deflection 2 k / lambda, tip abscissa (2 E(k) - K(k)) / lambda.
  mechanics::SolverOptions options;
  options.followStableBranch = true;
  const auto buckled = mechanics::solve(problem, options, 10);
  CHECK(buckled.stability == mechanics::Stability::Stable);
  const double lambdaL = kPi / 2 * std::sqrt(1.3);
  double lo = 0, hi = 0.999;
  for (int i = 0; i < 200; ++i) (std::comp_ellint_1(0.5 * (lo + hi)) < lambdaL ? lo : hi) = 0.5 * (lo + hi);
  const double k = 0.5 * (lo + hi), K = std::comp_ellint_1(k), Ek = std::comp_ellint_2(k);
  const Vec3 t = tip(problem, buckled.state);
  INFO("buckled tip " << t.transpose() << ", elastica x " << (2 * Ek - K) * L / K << ", deflection " << 2 * k * L / K);
  CHECK(t.x() == Approx((2 * Ek - K) * L / K).margin(0.05));
  CHECK(std::abs(t.y()) == Approx(2 * k * L / K).margin(0.05));
}

TEST_CASE("a round or square column's two buckling modes, crossing together, are found though det J keeps its sign",
          "[mechanics]") {
  // Clamped-free, 50 mm, E 100, Pcr = pi^2 EI / (4 L^2) about both axes alike: the two modes cross zero
  // at one load, det J never changes sign, and the straight column above Pcr was called stable.
  const double L = 50, E = 100;
  const auto column = [&](const Section& section, double I, double times) {
    const double critical = kPi * kPi * E * I / (4 * L * L);
    return cantilever(straight(Vec3::Zero(), Vec3(L, 0, 0), 1, 2), section, E, Vec3(-times * critical, 0, 0), Vec3::Zero(),
                      Vec3(0, 0, 1));
  };
  const std::vector<std::tuple<std::string, Section, double>> sections = {
      {"round 1 mm", Section::circle(1.0), kPi / 64}, {"square 0.8 mm", Section::rectangle(0.8, 0.8), std::pow(0.8, 4) / 12}};
  for (const auto& [name, section, I] : sections) {
    for (const double times : {1.3, 5.0}) {
      const StaticProblem problem(column(section, I, times));
      for (const int steps : {4, 7, 10}) {
        INFO(name << " at " << times << " Pcr, " << steps << " load steps");
        const auto solution = mechanics::solve(problem, {}, steps);
        REQUIRE(solution.criticalPoints.size() == 1);
        const auto& c = solution.criticalPoints[0];
        INFO("bracket [" << c.fromLoad << ", " << c.toLoad << "]");
        CHECK(c.crossings == 2);
        CHECK(c.kind == mechanics::CriticalPoint::Kind::Bifurcation);
        CHECK(c.toLoad - c.fromLoad <= 1e-3 + 1e-12);
        CHECK(c.fromLoad <= 1 / times + 2e-4);
        CHECK(c.toLoad >= 1 / times - 2e-4);
        CHECK(solution.stability == mechanics::Stability::Unstable);
        for (const auto& step : solution.steps) CHECK(step.determinantSign == 1);
      }
    }
    const StaticProblem below(column(section, I, 0.9));
    const auto solution = mechanics::solve(below, {}, 10);
    CHECK(solution.criticalPoints.empty());
    CHECK(solution.stability == mechanics::Stability::Stable);
  }
}

TEST_CASE("two buckling modes a few per cent apart within one load step are both found", "[mechanics]") {
  // A 1 x 0.98 mm rectangle: the weak mode at 1 / 1.3 = 0.769 of the load, the other at 0.769 / 0.9604
  // = 0.801. Four steps put both between 0.75 and 1: det J's sign at the steps never changes.
  const double L = 50, E = 100, I = std::pow(0.98, 3) / 12, critical = kPi * kPi * E * I / (4 * L * L);
  const StaticProblem problem(cantilever(straight(Vec3::Zero(), Vec3(L, 0, 0), 1, 2), Section::rectangle(1.0, 0.98), E,
                                         Vec3(-1.3 * critical, 0, 0), Vec3::Zero(), Vec3(0, 0, 1)));
  const auto solution = mechanics::solve(problem, {}, 4);
  for (const auto& step : solution.steps) CHECK(step.determinantSign == 1);
  REQUIRE(solution.criticalPoints.size() == 2);
  const double expected[] = {1 / 1.3, 1 / 1.3 / 0.9604};
  for (int i = 0; i < 2; ++i) {
    const auto& c = solution.criticalPoints[i];
    INFO("critical point " << i << ": bracket [" << c.fromLoad << ", " << c.toLoad << "]");
    CHECK(c.crossings == 1);
    CHECK(c.kind == mechanics::CriticalPoint::Kind::Bifurcation);
    CHECK(c.toLoad - c.fromLoad <= 1e-3 + 1e-12);
    CHECK(c.fromLoad <= expected[i] + 2e-4);
    CHECK(c.toLoad >= expected[i] - 2e-4);
  }
  // Two crossings: whether the second undid the first, the sign cannot tell.
  CHECK(solution.stability == mechanics::Stability::Undetermined);
}

TEST_CASE("a shallow arch that snaps through: the limit point the load path jumped past is reported where load "
          "control ends", "[mechanics]") {
  // A 30-degree circular arch of radius 100 mm (1 mm deep in its plane, 3 mm across), clamped at both
  // ends, pushed down at its crown. Load control from its drawn shape ends at a limit point (Newton
  // finds no equilibrium beyond it at any step); with a larger load and coarse steps Newton instead
  // lands on the snapped shape, and det J has the same sign there: before, that was "stable" and
  // nothing more.
  const auto arch = [](double force) {
    Design s;
    s.source = "arch";
    s.rods.push_back(test::rod("arch", arc(100, kPi / 2 - kPi / 12, kPi / 2 + kPi / 12), Section::rectangle(3, 1), 100, Vec3(0, 0, 1)));
    s.mechanics.present = true;
    s.mechanics.poissonRatio = 0.3;
    clamp(s, at("arch", mechanics::RodEnd::Start));
    clamp(s, at("arch", mechanics::RodEnd::End));
    test::load(s, atParameter("arch", 0.5), Vec3(0, -force, 0));
    return s;
  };
  // Where load control's branch ends, by steps of 1e-3 N halved down to 1e-8 N (until 2026-12-07 the
  // solve stopped there with an error; now it lands on the snapped branch from there).
  double limitForce = 0;
  const StaticProblem slow(arch(0.2));
  for (const auto& c : mechanics::solve(slow, {}, 200).criticalPoints)
    if (c.snapThrough) limitForce = 0.2 * c.fromLoad;
  INFO("load control's branch ends at " << limitForce << " N");
  REQUIRE(limitForce > 0.1);
  const StaticProblem problem(arch(1.0));
  for (const int steps : {4, 10}) {
    INFO(steps << " load steps");
    const auto solution = mechanics::solve(problem, {}, steps);
    REQUIRE(solution.criticalPoints.size() == 1);
    const auto& c = solution.criticalPoints[0];
    INFO("bracket [" << c.fromLoad << ", " << c.toLoad << "]");
    CHECK(c.snapThrough);
    CHECK(c.kind == mechanics::CriticalPoint::Kind::LimitPoint);
    CHECK(c.crossings == 1);
    CHECK(c.toLoad - c.fromLoad <= 1e-3 + 1e-12);
    CHECK(c.fromLoad <= limitForce + 1e-6);
    CHECK(c.toLoad >= limitForce - 1e-6);
    // The snapped arch hangs below its supports.
    CHECK(problem.position(solution.state, 0, 0.5).y() < problem.position(problem.referenceState(), 0, 0.0).y());
  }
}

TEST_CASE("a parabolic arch snaps through at one load whatever the step count (jumped, or stopped at its limit and "
          "continued)", "[mechanics]") {
  // Clamped at both ends, span 100 mm, rise 2 mm, 1 mm round, E 100 MPa, pushed down at its middle.
  // Its symmetric branch ends at a limit point near 0.00175 N (after an asymmetric bifurcation near
  // 0.00154 N). With 0.01 N, coarse steps jumped past it and det J's sign change was bisected across
  // the two branches: a "bifurcation", no warning; 60 steps and more stopped there with an error. With
  // 0.0019 N (the limit at 0.92 of the load) 3 to 40 steps stopped there (only 100 found the landing
  // from the branch's end pushed along its critical mode).
  const auto arch = [](double force) {
    Design s;
    s.source = "arch";
    s.rods.push_back(test::rod("arch", geometry::NurbsCurve(2, {0, 0, 0, 1, 1, 1}, {Vec3(-50, 0, 0), Vec3(0, 4, 0), Vec3(50, 0, 0)}),
                               Section::circle(1.0), 100));
    s.mechanics.present = true;
    clamp(s, at("arch", mechanics::RodEnd::Start));
    clamp(s, at("arch", mechanics::RodEnd::End));
    test::load(s, atParameter("arch", 0.5), Vec3(0, -force, 0));
    return s;
  };
  for (const auto& [force, stepCounts] : std::vector<std::pair<double, std::vector<int>>>{{0.01, {3, 10, 40, 100, 300}}, {0.0019, {3, 10, 40}}}) {
    const StaticProblem problem(arch(force));
    std::optional<double> snappedMiddle;
    for (const int steps : stepCounts) {
      INFO(force << " N, " << steps << " load steps");
      const auto solution = mechanics::solve(problem, {}, steps);
      std::vector<mechanics::CriticalPoint> snaps;
      for (const auto& c : solution.criticalPoints)
        if (c.snapThrough) snaps.push_back(c);
      REQUIRE(snaps.size() == 1);
      INFO("snap bracket [" << snaps[0].fromLoad << ", " << snaps[0].toLoad << "]");
      CHECK(snaps[0].kind == mechanics::CriticalPoint::Kind::LimitPoint);
      CHECK(snaps[0].toLoad - snaps[0].fromLoad <= 1e-3 + 1e-12);
      CHECK(snaps[0].fromLoad * force <= 0.0017535);
      CHECK(snaps[0].toLoad * force >= 0.0017534 - 1e-3 * force);
      CHECK(solution.stability == mechanics::Stability::Stable);  // the snapped arch, below its supports
      const double middle = problem.position(solution.state, 0, 0.5).y();
      CHECK(middle < -0.5);
      if (!snappedMiddle) snappedMiddle = middle;
      CHECK(middle == Approx(*snappedMiddle).margin(1e-6));
    }
  }
}

TEST_CASE("dips of |det J| next to Newton's failures neither crash nor invent critical points", "[mechanics]") {
  const double E = 100;
  const auto euler = [&](double L, double I) { return kPi * kPi * E * I / (4 * L * L); };
  const auto column = [&](mechanics::Design d) {  // the reproducers' Poisson ratio
    d.mechanics.poissonRatio = 0.4;
    return d;
  };
  SECTION("a 400 mm column of 1 x 0.9999965 mm at 3 Pcr in two steps: a search bound where Newton failed") {
    // A bound without an equilibrium was bisected as if it had one: "wrong state size", nothing written.
    const double I = std::pow(0.9999965, 3) / 12;
    const StaticProblem problem(column(cantilever(straight(Vec3::Zero(), Vec3(400, 0, 0), 1, 2), Section::rectangle(1.0, 0.9999965),
                                                  E, Vec3(-3 * euler(400, I), 0, 0), Vec3::Zero(), Vec3(0, 0, 1))));
    const auto solution = mechanics::solve(problem, {}, 2);
    REQUIRE_FALSE(solution.criticalPoints.empty());
    for (const auto& c : solution.criticalPoints) {
      INFO("bracket [" << c.fromLoad << ", " << c.toLoad << "]");
      CHECK(c.fromLoad <= 1 / 3.0 + 2e-4);
      CHECK(c.toLoad >= 1 / 3.0 - 2e-4);
    }
    CHECK(solution.stability != mechanics::Stability::Stable);
  }
  SECTION("a slender square column (L / h = 200) at 2 Pcr in one step: Newton fails next to the double zero") {
    const StaticProblem problem(column(cantilever(straight(Vec3::Zero(), Vec3(200, 0, 0), 1, 2), Section::rectangle(1, 1), E,
                                                  Vec3(-2 * euler(200, 1.0 / 12), 0, 0), Vec3::Zero(), Vec3(0, 0, 1))));
    const auto solution = mechanics::solve(problem, {}, 1);
    REQUIRE(solution.criticalPoints.size() == 1);
    const auto& c = solution.criticalPoints[0];
    CHECK(c.crossings == 2);
    CHECK(c.fromLoad <= 0.5 + 2e-4);
    CHECK(c.toLoad >= 0.5 - 2e-4);
    CHECK(solution.stability == mechanics::Stability::Unstable);
  }
  SECTION("a round column bowed by 2e-4 of its length at 1.5 Pcr: a smooth turn onto the buckled shape, no snap") {
    // Newton needed more than the search's dozen iterations where the path turns, which read as the
    // branch's end: "snap-through" at the Euler load.
    const geometry::NurbsCurve bowed(2, {0, 0, 0, 1, 1, 1}, {Vec3::Zero(), Vec3(25, 0.01, 0), Vec3(50, 0, 0)});
    const StaticProblem problem(column(cantilever(bowed, Section::circle(1.0), E, Vec3(-1.5 * euler(50, kPi / 64), 0, 0), Vec3::Zero())));
    const auto solution = mechanics::solve(problem, {}, 50);
    CHECK(solution.criticalPoints.empty());
    CHECK(solution.stability == mechanics::Stability::Stable);
  }
}

TEST_CASE("a load far below the rod's bending scale still moves it as beam theory says", "[mechanics]") {
  // 50 mm, 1 mm round, E 100: E I / L^2 = 2e-3 N. A tip force of 1e-12 N left a residual below the
  // absolute tolerance before any iteration: the drawn state passed for the solution (21 % off).
  const double L = 50, E = 100, I = kPi / 64, P = 1e-12;
  const Design s = cantilever(straight(Vec3::Zero(), Vec3(L, 0, 0), 1, 2), Section::circle(1.0), E, Vec3(0, 0, -P), Vec3::Zero());
  const StaticProblem problem(s);
  const auto solution = mechanics::solve(problem, {}, 5);
  const double deflection = -tip(problem, solution.state).z(), bending = P * L * L * L / (3 * E * I);
  // Within rounding: 8.5e-9 mm is 1.7e-10 of the rod's length, resolved to a few 1e-11 mm.
  INFO("tip deflection " << deflection << " mm, P L^3 / 3 E I " << bending << " mm (shear adds ~2e-4 of it)");
  CHECK(deflection == Approx(bending).epsilon(1e-2));
}

TEST_CASE("load steps: the planned number lands exactly on 1, cuts are reported", "[mechanics]") {
  const double L = 1.0, d = 0.1, E = 1000.0, EI = E * kPi * std::pow(d, 4) / 64;
  const Design s = cantilever(straight(Vec3::Zero(), Vec3(L, 0, 0), 1, 2), Section::circle(d), E, Vec3::Zero(),
                                    Vec3(0, 0, 1.5 * kPi * EI / L));
  const StaticProblem problem(s);
  mechanics::SolverOptions options;
  options.loadSteps = 10;
  const auto ten = mechanics::solve(problem, options, 10);
  REQUIRE(ten.steps.size() == 10);
  CHECK(ten.steps.back().loadFactor == 1.0);
  for (const auto& step : ten.steps) CHECK(step.cuts == 0);
  // Three quarters of a turn in one step is too much for Newton: the step is cut and says so.
  options.loadSteps = 1;
  options.maxIterations = 6;
  const auto one = mechanics::solve(problem, options, 1);
  REQUIRE(one.steps.size() > 1);
  CHECK(one.steps.front().cuts > 0);
  CHECK(one.steps.front().increment < 1.0);
  CHECK(one.steps.back().loadFactor == 1.0);
  double sum = 0;
  for (const auto& step : one.steps) sum += step.increment;
  CHECK(sum == Approx(1.0).epsilon(1e-12));
}

TEST_CASE("a structure that can move freely is a mechanism", "[mechanics]") {
  Design s = cantilever(straight(Vec3::Zero(), Vec3(1, 0, 0), 1, 2), Section::circle(0.1), 1000.0, Vec3(0, 0.01, 0), Vec3::Zero());
  s.mechanics.supports[0].kind = mechanics::SupportKind::Pinned;  // free to turn about the pin
  const StaticProblem problem(s);
  mechanics::SolverOptions options;
  CHECK_THROWS_WITH(mechanics::solve(problem, options, 1), Catch::Contains("mechanism") && !Catch::Contains("too slender"));
}

TEST_CASE("a clamped rod too slender for double precision is said to be so, not only a mechanism", "[mechanics]") {
  // L / d = 1e5: E A L^2 / E I = 1.6e11, past what the Jacobian's pivots resolve.
  Design s = cantilever(straight(Vec3::Zero(), Vec3(100, 0, 0), 1, 2), Section::circle(1e-3), 1000.0, Vec3(0, 1e-12, 0), Vec3::Zero());
  const StaticProblem problem(s);
  CHECK(problem.mostSlenderRod().second == Approx(1e5));
  CHECK_THROWS_WITH(mechanics::solve(problem, {}, 1),
                    Catch::Contains("too slender for double precision: rods[0]") && Catch::Contains("1e+05 times longer than thick"));
}
