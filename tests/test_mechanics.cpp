// mechanics/: the Cosserat rod solver against analytic and published solutions.
#include "mechanics/mechanics.hpp"
#include "mechanics/section_properties.hpp"
#include "tests/mechanics_fixture.hpp"

#include "geometry/geometry.hpp"

#include <boost/numeric/odeint.hpp>
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <limits>
#include <numbers>
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
using test::rod;
using test::straight;
using test::uniformKnots;

namespace {

constexpr double kPi = std::numbers::pi;

Design cantilever(NurbsCurve curve, const Section& section, double E, const Vec3& force, const Vec3& moment,
                  std::optional<Vec3> normal = std::nullopt) {
  Design s;
  s.source = "cantilever";
  s.rods.push_back(rod("beam", std::move(curve), section, E, normal));
  s.mechanics.present = true;
  s.mechanics.poissonRatio = 0.3;
  mechanics::Support clamp;
  clamp.at = at("beam", RodEnd::Start);
  s.mechanics.supports.push_back(clamp);
  mechanics::PointLoad load;
  load.at = at("beam", RodEnd::End);
  load.force = force;
  load.moment = moment;
  s.mechanics.loads.push_back(load);
  return s;
}

Vec3 tip(const StaticProblem& problem, const Eigen::VectorXd& x, std::size_t rodIndex = 0) {
  return problem.position(x, rodIndex, 1.0);
}

// The design's own basis, `refine` knots inserted per span.
mechanics::Discretization designBasis(int refine) {
  mechanics::Discretization d;
  d.degree = 0;
  d.refine = refine;
  return d;
}

// Every rod rebuilt at `degree` with `spans` uniform spans.
mechanics::Discretization rebuilt(int degree, int spans) {
  mechanics::Discretization d;
  d.degree = degree;
  d.spans = spans;
  return d;
}

Eigen::VectorXd solved(const StaticProblem& problem, int steps) {
  mechanics::SolverOptions options;
  options.loadSteps = steps;
  return mechanics::solve(problem, options, steps).state;
}

}  // namespace

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
  CHECK_THROWS_WITH(mechanics::solve(problem, options, 1), Catch::Contains("mechanism"));
}

// ---- Converged by default ------------------------------------------------------------------------

namespace {

// Bathe and Bolourchi's 45-degree bend: arc of radius 100 from the origin (tangent +x) to
// (70.71, 29.29, 0), square section 1 x 1, E = 1e7, nu = 0, J = 1/6, shear stiffness G A, dead
// load 600 along z.
Design batheBolourchi() {
  Design s = cantilever(arc(100, -kPi / 2, -kPi / 4, Vec3(0, 100, 0)), Section::rectangle(1, 1), 1e7,
                              Vec3(0, 0, 600), Vec3::Zero(), Vec3(0, 0, 1));
  s.mechanics.poissonRatio = 0.0;
  s.mechanics.rods.push_back({"beam", 1.0 / 6.0, 1.0, std::nullopt});
  return s;
}

// A graded cantilever: 50 mm long, 2 mm round, E falling linearly from 190 MPa at the clamp to
// 8 MPa at the tip (the calibration's range), nu = 0.3.
constexpr double kGradedLength = 50.0, kGradedDiameter = 2.0, kGradedNu = 0.3;
double gradedModulus(double s) { return 190.0 + (8.0 - 190.0) * s / kGradedLength; }

Design gradedCantilever(const Vec3& force, const Vec3& moment) {
  Design s;
  s.source = "graded";
  s.rods.emplace_back("beam", straight(Vec3::Zero(), Vec3(kGradedLength, 0, 0), 1, 2), Section::circle(kGradedDiameter),
                      std::nullopt, std::nullopt, CapStyle::Round, BSplineField(1, {0, 0, 1, 1}, {190.0, 8.0}));
  s.mechanics.present = true;
  s.mechanics.poissonRatio = kGradedNu;
  mechanics::Support clamp;
  clamp.at = at("beam", RodEnd::Start);
  s.mechanics.supports.push_back(clamp);
  mechanics::PointLoad load;
  load.at = at("beam", RodEnd::End);
  load.force = force, load.moment = moment;
  s.mechanics.loads.push_back(load);
  return s;
}

// The planar Cosserat (Reissner) cantilever under a tip force (0, -P), integrated as an ODE in the
// arc length by Boost.Odeint (Dormand-Prince, tolerances 1e-13) and shot on the clamp moment until
// the tip moment vanishes: code independent of the collocation solver. State (x, y, theta, m); with
// n = (0, -P) throughout: eps = n.d3 / EA, gamma = n.d1 / kGA, r' = (1 + eps) d3 + gamma d1,
// theta' = m / EI, m' = -(r' x n)_z.
Vec3 reissnerTip(double P) {
  using State = std::array<double, 4>;
  const double A = kPi * kGradedDiameter * kGradedDiameter / 4, I = kPi * std::pow(kGradedDiameter, 4) / 64;
  const double k = 6 * (1 + kGradedNu) / (7 + 6 * kGradedNu);  // Cowper, circle
  auto rhs = [&](const State& z, State& dz, double s) {
    const double E = gradedModulus(s), G = E / (2 * (1 + kGradedNu));
    const double c = std::cos(z[2]), sn = std::sin(z[2]);
    const double n3 = -P * sn, n1 = -P * c;  // n . d3, n . d1 for d3 = (c, sn), d1 = (-sn, c)
    const double eps = n3 / (E * A), gamma = n1 / (k * G * A);
    dz[0] = (1 + eps) * c - gamma * sn;
    dz[1] = (1 + eps) * sn + gamma * c;
    dz[2] = z[3] / (E * I);
    dz[3] = -(dz[0] * -P);  // -(x' n_y - y' n_x), n_x = 0
  };
  auto shoot = [&](double m0) {
    State z{0, 0, 0, m0};
    namespace ode = boost::numeric::odeint;
    ode::integrate_adaptive(ode::make_controlled(1e-13, 1e-13, ode::runge_kutta_dopri5<State>()), rhs, z, 0.0,
                            kGradedLength, kGradedLength / 1000);
    return z;
  };
  // Bisection on the clamp moment for a free tip (m(L) = 0): m(L) = m0 + P x(L) is positive for
  // m0 = 0 and negative for m0 = -1.1 P L.
  double lo = -1.1 * P * kGradedLength, hi = 0.0;
  REQUIRE(shoot(lo)[3] < 0);
  REQUIRE(shoot(hi)[3] > 0);
  for (int i = 0; i < 200 && hi - lo > 1e-15 * P * kGradedLength; ++i) {
    const double middle = 0.5 * (lo + hi);
    (shoot(middle)[3] < 0 ? lo : hi) = middle;
  }
  const State z = shoot(0.5 * (lo + hi));
  REQUIRE(std::abs(z[3]) < 1e-9 * P * kGradedLength);
  return Vec3(z[0], z[1], 0);
}

mechanics::Simulation simulated(const Design& s, int steps) {
  mechanics::SolverOptions options;
  options.loadSteps = steps;
  return mechanics::simulate(s, {}, options, steps);
}

}  // namespace

TEST_CASE("default discretization: the 45-degree bend within 0.01 of the converged tip", "[mechanics]") {
  const auto sim = simulated(batheBolourchi(), 6);
  const Vec3 t = tip(*sim.problem, sim.solution.state);
  INFO("tip " << t.transpose() << " on " << sim.problem->unknownCount() << " unknowns, " << sim.refinements
              << " refinements; estimated error " << sim.estimate.positionError);
  CHECK((t - Vec3(47.150, 15.685, 53.475)).norm() < 1e-2);
  CHECK((t - Vec3(47.2, 15.9, 53.4)).norm() < 0.3);  // Bathe and Bolourchi's published figures
  REQUIRE(sim.estimate.available);
  CHECK(sim.estimate.relative <= 1e-4);
}

TEST_CASE("default discretization: a graded cantilever within 0.1 % of independent references", "[mechanics]") {
  const double I = kPi * std::pow(kGradedDiameter, 4) / 64;
  SECTION("tip moment (71 degrees): the elastica by quadrature of theta(s) = integral of M / (E(s) I)") {
    // With no force, n = 0: no extension, no shear, and kappa = M / (E I) exactly.
    const double M = 71.4 * I / kGradedLength;
    const auto theta = [&](double s) {  // integral of M / (E I) for E linear in s
      return M * kGradedLength / ((190.0 - 8.0) * I) * std::log(190.0 / gradedModulus(s));
    };
    Vec3 exact = Vec3::Zero();  // composite Simpson, 2e5 intervals: error far below 1e-9 mm
    const int n = 200000;
    for (int i = 0; i <= n; ++i) {
      const double s = kGradedLength * i / n, w = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
      exact += w * Vec3(std::cos(theta(s)), std::sin(theta(s)), 0);
    }
    exact *= kGradedLength / n / 3;
    REQUIRE(theta(kGradedLength) * 180 / kPi == Approx(71.2).epsilon(1e-3));
    const auto sim = simulated(gradedCantilever(Vec3::Zero(), Vec3(0, 0, M)), 5);
    const Vec3 t = tip(*sim.problem, sim.solution.state);
    const double displacement = (exact - Vec3(kGradedLength, 0, 0)).norm();
    INFO("tip " << t.transpose() << ", exact " << exact.transpose() << "; " << sim.problem->unknownCount() << " unknowns");
    CHECK((t - exact).norm() < 1e-3 * displacement);
    REQUIRE(sim.estimate.available);
    CHECK(sim.estimate.relative <= 1e-4);
    CHECK((t - exact).norm() <= 10 * sim.estimate.positionError + 1e-9 * displacement);  // the estimate is honest
  }
  SECTION("tip force: the Reissner rod equations shot by an ODE integrator") {
    const double P = 0.5;
    const Vec3 exact = reissnerTip(P);
    const auto sim = simulated(gradedCantilever(Vec3(0, -P, 0), Vec3::Zero()), 5);
    const Vec3 t = tip(*sim.problem, sim.solution.state);
    const double displacement = (exact - Vec3(kGradedLength, 0, 0)).norm();
    INFO("tip " << t.transpose() << ", reference " << exact.transpose());
    REQUIRE(displacement > 20);  // a large deflection
    CHECK((t - exact).norm() < 1e-3 * displacement);
    REQUIRE(sim.estimate.available);
    CHECK(sim.estimate.relative <= 1e-4);
  }
}

TEST_CASE("the error estimate tracks the true error of a coarse discretization", "[mechanics]") {
  // The graded tip moment on fixed coarse bases without refinement: the estimate must not claim
  // much less than the true error, nor wildly more (measured: 0.5, 1.1 and 2.7 times it).
  const double I = kPi * std::pow(kGradedDiameter, 4) / 64, M = 71.4 * I / kGradedLength;
  const auto theta = [&](double s) { return M * kGradedLength / ((190.0 - 8.0) * I) * std::log(190.0 / gradedModulus(s)); };
  Vec3 exact = Vec3::Zero();
  const int n = 200000;
  for (int i = 0; i <= n; ++i) {
    const double s = kGradedLength * i / n, w = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
    exact += w * Vec3(std::cos(theta(s)), std::sin(theta(s)), 0);
  }
  exact *= kGradedLength / n / 3;
  for (int spans : {16, 32, 64}) {
    mechanics::AccuracyOptions accuracy;
    accuracy.maxRefinements = 0;
    mechanics::SolverOptions options;
    options.loadSteps = 5;
    const auto sim = mechanics::simulate(gradedCantilever(Vec3::Zero(), Vec3(0, 0, M)), rebuilt(6, spans), options, 5, accuracy);
    const double error = (tip(*sim.problem, sim.solution.state) - exact).norm();
    INFO(spans << " spans: true tip error " << error << ", estimate " << sim.estimate.positionError);
    REQUIRE(sim.estimate.available);
    CHECK(sim.estimate.positionError > 0.4 * error);
    CHECK(sim.estimate.positionError < 10 * error);
  }
}

TEST_CASE("automatic spans grow with slenderness, drawn turning and a falling modulus", "[mechanics]") {
  auto spansOf = [](const Design& s) { return StaticProblem(s).discretization().perRod.at(0); };
  const auto stubby = cantilever(straight(Vec3::Zero(), Vec3(10, 0, 0), 1, 2), Section::circle(2), 100, Vec3::Zero(), Vec3::Zero());
  const auto slender = cantilever(straight(Vec3::Zero(), Vec3(1000, 0, 0), 1, 2), Section::circle(2), 100, Vec3::Zero(), Vec3::Zero());
  const auto curved = cantilever(arc(640, 0, kPi / 2 - 1e-9), Section::circle(2), 100, Vec3::Zero(), Vec3::Zero(), Vec3(0, 0, 1));
  const auto graded = gradedCantilever(Vec3::Zero(), Vec3::Zero());
  CHECK(spansOf(stubby) <= 8);
  CHECK(spansOf(slender) > 3 * spansOf(stubby));
  CHECK(spansOf(curved) > spansOf(slender));  // about as long, but turning by a quarter turn
  CHECK(spansOf(graded) > 40);  // E / |E'| is 2.2 mm at the tip of a 50 mm rod
  // A tighter tolerance asks for more.
  mechanics::Discretization tight;
  tight.tolerance = 1e-6;
  CHECK(StaticProblem(slender, tight).discretization().perRod[0] > spansOf(slender));
}

TEST_CASE("the design's own basis (degree 0) is refined or refused, never used as drawn", "[mechanics]") {
  // A quarter-circle drawn as one rational quadratic span: 3 control points, one collocation point.
  Design arcDesign = cantilever(arc(40, -kPi / 2, 0, Vec3(0, 40, 0)), Section::circle(1.0), 100.0, Vec3(0, 0, -0.05),
                                      Vec3::Zero(), Vec3(0, 0, 1));
  mechanics::Discretization designOwn;
  designOwn.degree = 0;
  CHECK_THROWS_WITH(StaticProblem(arcDesign, designOwn), Catch::Contains("--degree 6"));
  // A quartic design is refined by knot insertion to the automatic span count.
  Design quartic = cantilever(straight(Vec3::Zero(), Vec3(20, 0, 0), 4, 5), Section::circle(1.0), 100.0, Vec3::Zero(),
                                    Vec3(0, 0, 0.5 * kPi * 100.0 * kPi / 64 / 20));
  const StaticProblem refined(quartic, designOwn);
  CHECK(refined.discretization().perRod[0] > 4);
  const Vec3 t = tip(refined, solved(refined, 4));
  const double R = 40 / kPi;  // quarter turn of a 20 mm rod: radius 2 L / pi
  CHECK((t - Vec3(R, R, 0)).norm() < 1e-3 * R);
  // Asked explicitly, the drawn basis is used as it is.
  CHECK(StaticProblem(quartic, designBasis(0)).discretization().perRod[0] == 1);
}

TEST_CASE("a kink of E(s) is followed by rebuilt rods, and on the design's basis kept off collocation points", "[mechanics]") {
  // A quartic rod, E falling from 100 to 20 MPa at its middle and back: kinked at u = 0.5.
  Design s = cantilever(straight(Vec3::Zero(), Vec3(20, 0, 0), 4, 5), Section::circle(1.0), 100.0, Vec3(0, -0.05, 0),
                              Vec3::Zero());
  s.rods[0] = Rod("beam", s.rods[0].centerline(), s.rods[0].section(), std::nullopt, std::nullopt, CapStyle::Round,
                  BSplineField(1, {0, 0, 0.5, 1, 1}, {100, 20, 100}));
  // Rebuilt rods get a C1 knot at the kink (never a collocation point) and converge fast: the tip
  // on 16 and 32 spans agrees far better than with a plain knot there (order 2.5: 5e-3 here).
  const Vec3 t16 = tip(StaticProblem(s, rebuilt(6, 16)), solved(StaticProblem(s, rebuilt(6, 16)), 4));
  const StaticProblem p32(s, rebuilt(6, 32));
  const Vec3 t32 = tip(p32, solved(p32, 4));
  INFO("tip " << t16.transpose() << " (16 spans), " << t32.transpose() << " (32 spans)");
  CHECK((t16 - t32).norm() < 3e-4 * (t32 - Vec3(20, 0, 0)).norm());
  CHECK_NOTHROW(StaticProblem(s, rebuilt(5, 10)));  // odd degrees too
  // On the design's quartic basis, two knots inserted put a collocation point (the mean of the
  // knots 0, 1/3, 2/3, 1) on the kink: refused, naming the option; chosen automatically, the
  // refinement avoids it.
  CHECK_THROWS_WITH(StaticProblem(s, designBasis(2)), Catch::Contains("--refine") && Catch::Contains("kink at u = 0.5"));
  mechanics::Discretization automatic;
  automatic.degree = 0;
  CHECK_NOTHROW(StaticProblem(s, automatic));
}

TEST_CASE("a state moves between discretizations of one design", "[mechanics]") {
  const auto s = batheBolourchi();
  const StaticProblem coarse(s, rebuilt(6, 8)), fine(s, rebuilt(6, 20));
  const Eigen::VectorXd x = solved(coarse, 6);
  const Eigen::VectorXd moved = fine.transferredState(coarse, x);
  for (double u : {0.0, 0.3, 0.77, 1.0}) {
    CHECK((fine.position(moved, 0, u) - coarse.position(x, 0, u)).norm() < 1e-3);
    CHECK((fine.rotation(moved, 0, u) - coarse.rotation(x, 0, u)).norm() < 1e-4);
  }
  // Onto the same discretization it changes nothing.
  CHECK((coarse.transferredState(coarse, x) - x).lpNorm<Eigen::Infinity>() < 1e-10);
  CHECK_THROWS_AS(fine.transferredState(coarse, Eigen::VectorXd::Zero(5)), std::invalid_argument);
}

TEST_CASE("the deformed design keeps its mechanics block, rod ends by name", "[mechanics]") {
  Design s = batheBolourchi();
  s.mechanics.loads[0].at = mechanics::RodEndRef{};
  s.mechanics.loads[0].at.point = s.rods[0].centerline().points().back();
  s.mechanics.loads[0].at.path = "test";
  const StaticProblem problem(s, rebuilt(6, 16));
  const Design deformed = problem.deformedStructure(solved(problem, 6));
  REQUIRE(deformed.mechanics.present);
  REQUIRE(deformed.mechanics.loads.size() == 1);
  CHECK_FALSE(deformed.mechanics.loads[0].at.point.has_value());
  CHECK(deformed.mechanics.loads[0].at.rod == "beam");
  CHECK(deformed.mechanics.loads[0].at.end == RodEnd::End);
  CHECK(deformed.mechanics.rods.size() == 1);
  // It can be simulated again: as the new drawn state it is an equilibrium at load 0.
  const StaticProblem again(deformed);
  Eigen::VectorXd residual;
  again.evaluate(again.referenceState(), 0.0, residual);
  CHECK(residual.lpNorm<Eigen::Infinity>() < 1e-9);
}
