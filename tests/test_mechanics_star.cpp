// mechanics/: many rods meeting at one joint (a star). Against frame theory where symmetry gives
// it, and the problem's size (Jacobian entries, LU factor entries, heap) growing linearly with the
// number of rods, where the node's equations once grew with its square.
#include "mechanics/mechanics.hpp"
#include "mechanics/section_properties.hpp"
#include "tests/heap_in_use.hpp"
#include "tests/mechanics_fixture.hpp"

#include "geometry/geometry.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <iomanip>
#include <string>

#include "tests/mechanics_names.hpp"  // last: using-declarations

namespace {

constexpr double kL = 1.0, kD = 0.05, kE = 1000.0, kNu = 0.3;

// `count` straight rods from the hub at the origin out to a rim of radius L in the xy-plane at
// equal angles, each clamped at the rim; `force` acts at the hub.
Design star(int count, const Vec3& force) {
  Design s;
  s.source = "star-" + std::to_string(count);
  for (int k = 0; k < count; ++k) {
    const double angle = 2 * test::kPi * k / count;
    const Vec3 rim(kL * std::cos(angle), kL * std::sin(angle), 0);
    s.rods.push_back(test::rod("spoke" + std::to_string(k), straight(Vec3::Zero(), rim), Section::circle(kD), kE));
    test::clamp(s, at("spoke" + std::to_string(k), RodEnd::End));
  }
  s.mechanics.present = true;
  s.mechanics.poissonRatio = kNu;
  s.mechanics.loadSteps = 1;
  test::load(s, atPoint(Vec3::Zero()), force);
  return s;
}

// Sizes of a star's discrete problem: heap it holds, Jacobian entries, LU factor entries.
struct Sizes {
  double heap = 0, jacobian = 0, factors = 0;
};

Sizes sizesOf(int count) {
  const std::uint64_t before = tests::heapBytesInUse();
  const StaticProblem problem(star(count, Vec3(0, 0, 1e-6)));
  Sizes s;
  s.heap = static_cast<double>(tests::heapBytesInUse() - before);
  Eigen::VectorXd residual;
  Eigen::SparseMatrix<double> jacobian;
  problem.evaluate(problem.referenceState(), 0.0, residual, &jacobian);
  mechanics::JacobianLU lu(7);
  REQUIRE(lu.factorize(jacobian));
  s.jacobian = static_cast<double>(jacobian.nonZeros());
  s.factors = static_cast<double>(lu.factorEntries());
  return s;
}

}  // namespace

TEST_CASE("a symmetric star under a load along its axis shares it equally - frame theory", "[mechanics][joints][star]") {
  // By symmetry the hub does not turn, so every spoke is a beam clamped at the rim and guided at
  // the hub carrying F / N: the hub deflects (F / N) (L^3 / 12 EI + L / kGA) (Timoshenko). The load
  // is small enough for the geometric nonlinearity (~ (w / r_gyration)^2) to stay near 5e-6.
  const int count = 96;
  const double F = 1e-7 * count;
  const auto props = mechanics::sectionProperties(Section::circle(kD), kNu);
  const double EI = kE * props.inertia1, kGA = props.shearFactor * kE / (2 * (1 + kNu)) * props.area;
  const double theory = F / count * (kL * kL * kL / (12 * EI) + kL / kGA);

  const Design s = star(count, Vec3(0, 0, F));
  const mechanics::Simulation sim = mechanics::simulate(s, {}, {}, 1);
  REQUIRE(sim.problem->jointCount() == 1);
  const Eigen::VectorXd& x = sim.solution.state;
  const StaticProblem& p = *sim.problem;
  const Vec3 hub = p.position(x, 0, 0.0);
  INFO(std::setprecision(10) << "hub moved " << hub.transpose() << "; frame theory " << theory << "; estimated relative error "
                             << sim.estimate.relative);
  CHECK(hub.z() == Approx(theory).epsilon(1e-4));
  CHECK(hub.head<2>().norm() < 1e-4 * theory);
  CHECK((p.rotation(x, 0, 0.0) - p.rotation(p.referenceState(), 0, 0.0)).norm() < 1e-3 * theory / kL);
  // Every spoke bends the same way about its own axis: its middle rises by the same amount.
  double low = 1e300, high = -1e300;
  for (std::size_t r = 0; r < p.rodCount(); ++r) {
    const double rise = p.position(x, r, 0.5).z();
    low = std::min(low, rise), high = std::max(high, rise);
  }
  CHECK(high - low < 1e-4 * theory);
  CHECK(low > 0.4 * theory);
}

TEST_CASE("a star's problem grows linearly with its rods: Jacobian, factors and heap", "[mechanics][joints][star]") {
  // Counted, not timed. A node's rows once formed one dense block of (7 N) x (14 N) entries, so its
  // layout and scratch grew with N^2 (its tiles now couple each end with the first one only); and
  // KLU, its rows scaled by their largest entry, took the joint's balance rows as off-diagonal
  // pivots, 1.27 times the factor entries per rod at 400 rods as at 100 (scaled by their sum: 1.00).
  const Sizes small = sizesOf(100), large = sizesOf(400);
  const auto perRod = [](double value, int count) { return value / count; };
  INFO("per rod at 100 and 400 rods: Jacobian " << perRod(small.jacobian, 100) << ", " << perRod(large.jacobian, 400)
                                                << "; factors " << perRod(small.factors, 100) << ", " << perRod(large.factors, 400)
                                                << "; heap " << perRod(small.heap, 100) << ", " << perRod(large.heap, 400));
  CHECK(perRod(large.jacobian, 400) < 1.05 * perRod(small.jacobian, 100));
  CHECK(perRod(large.factors, 400) < 1.05 * perRod(small.factors, 100));
  CHECK(perRod(large.heap, 400) < 1.1 * perRod(small.heap, 100));
}

TEST_CASE("the memory estimate counts the problem's heap and bounds KLU's factors", "[mechanics][star][memory]") {
  for (int count : {25, 200}) {
    const std::uint64_t before = tests::heapBytesInUse();
    const StaticProblem problem(star(count, Vec3(0, 0, 1e-6)));
    const double held = static_cast<double>(tests::heapBytesInUse() - before);
    const mechanics::SolveMemory estimate = problem.memoryEstimate();
    Eigen::VectorXd residual;
    Eigen::SparseMatrix<double> jacobian;
    problem.evaluate(problem.referenceState(), 0.0, residual, &jacobian);
    mechanics::JacobianLU lu(7);
    REQUIRE(lu.factorize(jacobian));
    const double factors = static_cast<double>(lu.factorEntries()) * (sizeof(double) + sizeof(int));
    INFO(count << " rods: problem " << estimate.problem << " estimated, " << held << " held; factors " << factors
               << ", solve estimate " << estimate.solve);
    CHECK(static_cast<double>(estimate.problem) > 0.9 * held);
    CHECK(static_cast<double>(estimate.problem) < 1.5 * held);
    CHECK(static_cast<double>(estimate.solve) > factors);
  }
}
