// mechanics/: the Cosserat rod solver against analytic and published solutions.
#include "mechanics/mechanics.hpp"
#include "mechanics/section_properties.hpp"
#include "tests/mechanics_fixture.hpp"

#include "geometry/geometry.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <random>

using namespace rodfab;
using geometry::BSplineField;
using geometry::CapStyle;
using geometry::NurbsCurve;
using geometry::Rod;
using geometry::Section;
using geometry::Vec3;
using mechanics::Design;
using mechanics::RodEnd;
using mechanics::StaticProblem;
using test::arc;
using test::at;
using test::cantilever;
using test::designBasis;
using test::kPi;
using test::rebuilt;
using test::rod;
using test::solved;
using test::straight;
using test::tip;

TEST_CASE("section properties: areas, second moments and torsion constants", "[mechanics]") {
  const auto c = mechanics::sectionProperties(Section::circle(2.0), 0.3);
  CHECK(c.area == Approx(kPi));
  CHECK(c.inertia1 == Approx(kPi / 4));
  CHECK(c.torsionConstant == Approx(kPi / 2));
  CHECK(c.shearFactor == Approx(6 * 1.3 / 8.8));
  const auto sq = mechanics::sectionProperties(Section::rectangle(1.0, 1.0), 0.0);
  CHECK(sq.inertia1 == Approx(1.0 / 12));
  CHECK(sq.torsionConstant == Approx(0.140577).epsilon(1e-5));  // Roark: 0.1406 a^4 for a square
  const auto r = mechanics::sectionProperties(Section::rectangle(2.0, 0.5), 0.0);
  CHECK(r.inertia1 == Approx(2.0 * 0.125 / 12));
  CHECK(r.inertia2 == Approx(0.5 * 8.0 / 12));
  CHECK(r.torsionConstant == Approx(0.281 * 2.0 * 0.125).epsilon(1e-3));  // beta = 0.281 for a/b = 4 (Roark)
  const auto e = mechanics::sectionProperties(Section::ellipse(4.0, 2.0), 0.3);
  CHECK(e.area == Approx(2 * kPi));
  CHECK(e.inertia1 == Approx(kPi * 2 * 1 / 4));
  CHECK(e.inertia2 == Approx(kPi * 8 * 1 / 4));
  CHECK(e.torsionConstant == Approx(kPi * 8 * 1 / 5));
}

TEST_CASE("the reference configuration is an exact solution at load 0", "[mechanics]") {
  Design s = cantilever(arc(10, 0, 1.2), Section::rectangle(1.0, 0.6), 100.0, Vec3(0, 0, 1), Vec3::Zero(), Vec3(0, 0, 1));
  const StaticProblem problem(s, designBasis(3));
  Eigen::VectorXd residual;
  problem.evaluate(problem.referenceState(), 0.0, residual);
  CHECK(residual.lpNorm<Eigen::Infinity>() < 1e-12);
  problem.evaluate(problem.referenceState(), 1.0, residual);
  CHECK(residual.lpNorm<Eigen::Infinity>() > 1e-6);  // the load is felt
}

TEST_CASE("the analytic Jacobian matches central finite differences", "[mechanics]") {
  // Two rods at an angle with a rigid joint, a rational arc, varying E, a distributed load, an
  // end moment, a pinned support with a displacement, in a perturbed (non-equilibrium) state.
  Design s;
  s.source = "jacobian";
  NurbsCurve a = straight(Vec3(0, 0, 0), Vec3(4, 0, 1), 4, 7);
  s.rods.push_back(Rod("a", a, Section::ellipse(0.8, 0.5), Vec3(0, 0, 1), std::nullopt, CapStyle::Round,
                       BSplineField(3, {0, 0, 0, 0, 0.5, 1, 1, 1, 1}, {100, 140, 80, 120, 90})));
  s.rods.push_back(rod("b", arc(3, 0, 1.0, Vec3(1, 0, 1)), Section::circle(0.7), 60.0));
  s.mechanics.present = true;
  mechanics::Support pin;
  pin.at = at("a", RodEnd::Start);
  pin.kind = mechanics::SupportKind::Pinned;
  pin.displacement = Vec3(0.1, -0.2, 0.05);
  s.mechanics.supports.push_back(pin);
  mechanics::Support clamp;
  clamp.at = at("b", RodEnd::End);
  clamp.rotation = Vec3(0.2, 0.1, -0.3);
  s.mechanics.supports.push_back(clamp);
  mechanics::PointLoad load;
  load.at = at("a", RodEnd::Start);
  load.moment = Vec3(1, 2, 3);
  s.mechanics.loads.push_back(load);
  s.mechanics.distributedLoads.push_back({"b", Vec3(0.3, -0.2, 0.5), "test"});
  const StaticProblem problem(s, designBasis(1));
  REQUIRE(problem.jointCount() == 1);

  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.05, 0.05);
  Eigen::VectorXd x = problem.referenceState();
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += jitter(rng);
  Eigen::VectorXd f;
  Eigen::SparseMatrix<double> J;
  problem.evaluate(x, 0.7, f, &J);
  const Eigen::MatrixXd dense = Eigen::MatrixXd(J);
  double worst = 0, scale = dense.cwiseAbs().maxCoeff();
  for (Eigen::Index c = 0; c < x.size(); ++c) {
    const double h = 1e-6;
    Eigen::VectorXd xp = x, xm = x, fp, fm;
    xp[c] += h, xm[c] -= h;
    problem.evaluate(xp, 0.7, fp);
    problem.evaluate(xm, 0.7, fm);
    const Eigen::VectorXd fd = (fp - fm) / (2 * h);
    worst = std::max(worst, (fd - dense.col(c)).lpNorm<Eigen::Infinity>());
  }
  INFO("largest |J - FD| " << worst << " of entries up to " << scale);
  CHECK(worst < 1e-7 * scale);
}

TEST_CASE("an end moment rolls a cantilever into a circle", "[mechanics]") {
  const double L = 1.0, d = 0.1, E = 1000.0;
  const double EI = E * kPi * std::pow(d, 4) / 64;
  SECTION("intermediate moments follow x = EI/M sin(ML/EI), y = EI/M (1 - cos(ML/EI))") {
    for (double fraction : {0.25, 0.5, 0.75}) {
      const double M = fraction * 2 * kPi * EI / L;
      const StaticProblem problem(cantilever(straight(Vec3::Zero(), Vec3(L, 0, 0), 4, 100), Section::circle(d), E,
                                             Vec3::Zero(), Vec3(0, 0, M)));
      const Eigen::VectorXd x = solved(problem, 4);
      const Vec3 t = tip(problem, x);
      INFO("fraction " << fraction);
      CHECK(std::abs(t.x() - EI / M * std::sin(M * L / EI)) < 1e-6 * L);
      CHECK(std::abs(t.y() - EI / M * (1 - std::cos(M * L / EI))) < 1e-6 * L);
      CHECK(std::abs(t.z()) < 1e-12);
    }
  }
  SECTION("M = 2 pi EI / L closes the circle: the tip returns to the root") {
    const StaticProblem problem(cantilever(straight(Vec3::Zero(), Vec3(L, 0, 0), 4, 132), Section::circle(d), E,
                                           Vec3::Zero(), Vec3(0, 0, 2 * kPi * EI / L)));
    const Eigen::VectorXd x = solved(problem, 10);
    const Vec3 t = tip(problem, x);
    INFO("tip " << t.transpose());
    CHECK(t.norm() < 1e-6 * L);
    // The end frame has turned a full turn: back to the identity.
    const Eigen::Matrix3d turned = problem.rotation(x, 0, 1.0) * problem.rotation(problem.referenceState(), 0, 1.0).transpose();
    CHECK((turned - Eigen::Matrix3d::Identity()).norm() < 1e-5);
  }
}


TEST_CASE("the roll-up converges at the order of the collocation degree", "[mechanics]") {
  // Tip error of the cantilever under M = pi EI / (2 L) (a quarter turn). IGA collocation at the
  // Greville points converges like h^p for even p and h^(p-1) for odd p.
  const double L = 1.0, d = 0.1, E = 1000.0, EI = E * kPi * std::pow(d, 4) / 64, M = 0.5 * kPi * EI / L;
  auto error = [&](int p, int spans) {
    const StaticProblem problem(cantilever(straight(Vec3::Zero(), Vec3(L, 0, 0), p, spans + p), Section::circle(d), E,
                                           Vec3::Zero(), Vec3(0, 0, M)),
                                designBasis(0));
    const Vec3 t = tip(problem, solved(problem, 3));
    return (t - Vec3(EI / M * std::sin(M * L / EI), EI / M * (1 - std::cos(M * L / EI)), 0)).norm() / L;
  };
  const std::vector<std::pair<int, double>> expected = {{2, 2.0}, {3, 2.0}, {4, 4.0}};
  for (const auto& [p, order] : expected) {
    const double coarse = error(p, 32), fine = error(p, 64);
    const double observed = std::log2(coarse / fine);
    INFO("degree " << p << ": error " << coarse << " (32 spans), " << fine << " (64 spans), order " << observed);
    CHECK(observed > order - 0.3);
  }
}

TEST_CASE("large-deflection cantilever under a tip force matches Mattiasson's elliptic-integral solution", "[mechanics]") {
  // EI = 1, L = 1 and L / d = 100, so extension and shear add at most 2e-4 L at P L^2 / EI = 10.
  // (More slender rods need more spans: primal collocation locks mildly in shear and extension.)
  const double L = 1.0, d = 0.01, E = 64.0 / (kPi * std::pow(d, 4));
  struct Case { double load, u, w; };
  for (const Case c : {Case{1, 0.05643, 0.30172}, Case{2, 0.16064, 0.49346}, Case{5, 0.38763, 0.71379},
                       Case{10, 0.55500, 0.81061}}) {
    const StaticProblem problem(cantilever(straight(Vec3::Zero(), Vec3(L, 0, 0), 4, 68), Section::circle(d), E,
                                           Vec3(0, -c.load, 0), Vec3::Zero()));
    const Vec3 t = tip(problem, solved(problem, static_cast<int>(c.load) + 1));
    INFO("P L^2 / EI = " << c.load << ": tip " << t.transpose());
    CHECK(std::abs((L - t.x()) / L - c.u) < 1e-3);
    CHECK(std::abs(-t.y() / L - c.w) < 1e-3);
  }
}

TEST_CASE("45-degree bend under a transverse tip load matches Bathe and Bolourchi", "[mechanics]") {
  // Arc of radius 100 from the origin (tangent +x) to (70.71, 29.29, 0), square section 1 x 1,
  // E = 1e7, nu = 0, J = 1/6, shear stiffness G A, dead load 600 along z.
  Design s = cantilever(arc(100, -kPi / 2, -kPi / 4, Vec3(0, 100, 0)), Section::rectangle(1, 1), 1e7,
                              Vec3(0, 0, 600), Vec3::Zero(), Vec3(0, 0, 1));
  s.mechanics.poissonRatio = 0.0;
  s.mechanics.rods.push_back({"beam", 1.0 / 6.0, 1.0, std::nullopt});
  const StaticProblem problem(s, rebuilt(4, 32));
  const Vec3 t = tip(problem, solved(problem, 6));
  INFO("tip " << t.transpose());
  CHECK(std::abs(t.x() - 47.2) < 0.3);
  CHECK(std::abs(t.y() - 15.9) < 0.3);
  CHECK(std::abs(t.z() - 53.4) < 0.3);
}

TEST_CASE("a clamped-free column's imperfection response blows up at the Euler load", "[mechanics]") {
  // Column along z with EI = 1, L = 1, initially bent into its buckling mode with 1e-4 L at the
  // tip. Linear theory gives the added tip deflection w = w0 (P / Pcr) / (1 - P / Pcr), so w / P
  // against w is a line of slope 1 / Pcr (Southwell): its asymptote is where the response blows up.
  const double L = 1.0, d = 0.01, E = 64.0 / (kPi * std::pow(d, 4)), w0 = 1e-4 * L;
  const double euler = kPi * kPi / (4 * L * L);
  const int p = 4, count = 44;
  NurbsCurve column = straight(Vec3::Zero(), Vec3(0, 0, L), p, count);
  std::vector<Vec3> pts = column.points();
  for (Vec3& q : pts) q.x() = w0 * (1 - std::cos(kPi * q.z() / (2 * L)));
  Design s = cantilever(NurbsCurve(p, column.knots(), pts), Section::circle(d), E, Vec3(0, 0, -0.95 * euler), Vec3::Zero());
  const StaticProblem problem(s);
  const double tip0 = problem.position(problem.referenceState(), 0, 1.0).x();
  std::vector<double> deflection, load;
  mechanics::SolverOptions options;
  options.loadSteps = 19;
  mechanics::solve(problem, options, 19, [&](const mechanics::LoadStepReport& r, const Eigen::VectorXd& x) {
    if (r.loadFactor < 0.5) return;
    deflection.push_back(problem.position(x, 0, 1.0).x() - tip0);
    load.push_back(r.loadFactor * 0.95 * euler);
  });
  REQUIRE(deflection.size() >= 8);
  // Least-squares line through (w, w / P).
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double n = static_cast<double>(deflection.size());
  for (std::size_t i = 0; i < deflection.size(); ++i) {
    const double x = deflection[i], y = deflection[i] / load[i];
    sx += x, sy += y, sxx += x * x, sxy += x * y;
  }
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  const double critical = 1.0 / slope;
  INFO("Southwell critical load " << critical << ", Euler " << euler << ", largest deflection " << deflection.back());
  CHECK(std::abs(critical / euler - 1) < 0.01);
  CHECK(deflection.back() > 10 * w0);  // it did blow up near the end
}

TEST_CASE("an L-shaped frame with a rigid joint matches frame theory", "[mechanics]") {
  // Post from the origin up to (0, 0, a), clamped at its foot; arm from its top to (b, 0, a); a
  // small load P down at the arm's end. Timoshenko frame theory: the tip drops by
  // P (b^3 / 3EI + a b^2 / EI + a / EA + b / kGA) and moves sideways by P b a^2 / 2EI.
  const double a = 1.0, b = 0.8, d = 0.05, E = 1000.0, nu = 0.3, P = 1e-9;  // geometric nonlinearity ~ 3e-6
  Design s;
  s.source = "frame";
  s.rods.push_back(rod("post", straight(Vec3::Zero(), Vec3(0, 0, a), 4, 12), Section::circle(d), E));
  s.rods.push_back(rod("arm", straight(Vec3(0, 0, a), Vec3(b, 0, a), 4, 12), Section::circle(d), E));
  s.mechanics.present = true;
  s.mechanics.poissonRatio = nu;
  mechanics::Support clamp;
  clamp.at = at("post", RodEnd::Start);
  s.mechanics.supports.push_back(clamp);
  mechanics::PointLoad load;
  load.at.point = Vec3(b, 0, a);  // by position, as a design file may give it
  load.at.path = "test";
  load.force = Vec3(0, 0, -P);
  s.mechanics.loads.push_back(load);
  const StaticProblem problem(s);
  REQUIRE(problem.jointCount() == 1);
  const Eigen::VectorXd x = solved(problem, 1);
  const Vec3 moved = tip(problem, x, 1) - Vec3(b, 0, a);
  const auto props = mechanics::sectionProperties(Section::circle(d), nu);
  const double EI = E * props.inertia1, EA = E * props.area, kGA = props.shearFactor * E / (2 * (1 + nu)) * props.area;
  const double drop = P * (b * b * b / (3 * EI) + a * b * b / EI + a / EA + b / kGA);
  const double sideways = P * b * a * a / (2 * EI);
  INFO("tip moved by " << moved.transpose() << "; frame theory " << drop << " down, " << sideways << " sideways");
  CHECK(-moved.z() == Approx(drop).epsilon(1e-4));
  CHECK(std::abs(moved.x()) == Approx(sideways).epsilon(1e-4));
  CHECK(std::abs(moved.y()) < 1e-12);
}

TEST_CASE("a bent rod cut in two and joined rigidly deforms like the whole rod", "[mechanics]") {
  // A smooth spatial bend (a quartic curve) loaded in three directions, once as one rod and once
  // as its two halves (exact subdivision at u = 1/2) with an inferred rigid joint.
  const NurbsCurve whole(4, {0, 0, 0, 0, 0, 1, 1, 1, 1, 1},
                         {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0.5, 0.3), Vec3(2.5, 1.5, 0.6), Vec3(2.6, 2.5, 1.0)});
  NurbsCurve split = whole;
  for (int i = 0; i < 4; ++i) split = split.withKnotInserted(0.5);
  const auto& pts = split.points();
  const NurbsCurve first(4, {0, 0, 0, 0, 0, 0.5, 0.5, 0.5, 0.5, 0.5}, std::vector<Vec3>(pts.begin(), pts.begin() + 5));
  const NurbsCurve second(4, {0.5, 0.5, 0.5, 0.5, 0.5, 1, 1, 1, 1, 1}, std::vector<Vec3>(pts.begin() + 4, pts.end()));
  REQUIRE((first.point(0.5) - whole.point(0.5)).norm() < 1e-12);
  REQUIRE((second.point(0.75) - whole.point(0.75)).norm() < 1e-12);

  struct TipMotion {
    Vec3 move;
    Eigen::Matrix3d turn;
  };
  auto solveTip = [&](std::vector<NurbsCurve> parts, int spans) {
    Design s;
    s.source = "bend";
    for (std::size_t i = 0; i < parts.size(); ++i)
      // A circle: each rod's rotation-minimizing frame starts afresh, which only a round section ignores.
      s.rods.push_back(rod("part" + std::to_string(i), parts[i], Section::circle(0.25), 500.0));
    s.mechanics.present = true;
    mechanics::Support clamp;
    clamp.at = at("part0", RodEnd::Start);
    s.mechanics.supports.push_back(clamp);
    mechanics::PointLoad load;
    load.at = at("part" + std::to_string(parts.size() - 1), RodEnd::End);
    load.force = Vec3(0.002, -0.003, -0.005);
    load.moment = Vec3(0.001, 0.0, 0.002);
    s.mechanics.loads.push_back(load);
    const StaticProblem problem(s, rebuilt(4, spans));
    REQUIRE(problem.jointCount() == parts.size() - 1);
    const Eigen::VectorXd x = solved(problem, 4);
    const std::size_t last = parts.size() - 1;
    const double u = parts[last].domainEnd();
    const Eigen::VectorXd& x0 = problem.referenceState();
    return TipMotion{problem.position(x, last, u) - problem.position(x0, last, u),
                     problem.rotation(x, last, u) * problem.rotation(x0, last, u).transpose()};
  };
  const TipMotion one = solveTip({whole}, 64), two = solveTip({first, second}, 32);
  const Vec3 oneMove = one.move, twoMove = two.move;
  const Eigen::Matrix3d oneTurn = one.turn, twoTurn = two.turn;
  INFO("one rod: tip moves " << oneMove.transpose() << "; two rods: " << twoMove.transpose());
  REQUIRE(oneMove.norm() > 0.3);  // a large deflection
  CHECK((oneMove - twoMove).norm() < 1e-5 * oneMove.norm());
  CHECK((oneTurn - twoTurn).norm() < 1e-5);
}
