// mechanics/: designs a solve would answer wrongly or fail on without saying why, refused before any
// solve and named by their field: a centerline whose parameter stops, stiffness overrides and loads no
// section or rod of the design can have.
#include "mechanics/mechanics.hpp"
#include "tests/mechanics_fixture.hpp"

#include "geometry/geometry.hpp"

#include <catch2/catch.hpp>

using namespace rodfab;
using geometry::Section;
using geometry::Vec3;
using mechanics::Design;
using mechanics::StaticProblem;
using test::arc;
using test::cantilever;
using test::rebuilt;
using test::straight;

TEST_CASE("a centerline whose parameter stops or nearly stops is refused, naming where", "[mechanics]") {
  // A straight quadratic with its middle control point repeated: r'(0.5) = 0 between collocation
  // points. As a cantilever it bent 10 % too little (tip 4.616 mm against the elastica's 5.139), nothing said.
  const geometry::NurbsCurve stopping(2, {0, 0, 0, 0.5, 1, 1, 1}, {Vec3(0, 0, 0), Vec3(10, 0, 0), Vec3(10, 0, 0), Vec3(20, 0, 0)});
  CHECK_THROWS_WITH(StaticProblem(cantilever(stopping, Section::circle(1.0), 100.0, Vec3(0, -0.01, 0), Vec3::Zero()), rebuilt(6, 80)),
                    Catch::Contains("rods[0].centerline: the centerline's derivative vanishes at u = 0.5"));
  // Nearly: the first leg 1 um of a 20 mm rod, the speed 20,000 times lower at u = 0.
  const geometry::NurbsCurve crawling(2, {0, 0, 0, 1, 1, 1}, {Vec3(0, 0, 0), Vec3(1e-3, 0, 0), Vec3(20, 0, 0)});
  CHECK_THROWS_WITH(StaticProblem(cantilever(crawling, Section::circle(1.0), 100.0, Vec3(0, -0.01, 0), Vec3::Zero())),
                    Catch::Contains("rods[0].centerline: its parameter runs 19999 times slower at u = 0 "));
  // A circle's speed is even, a cubic's through unevenly spaced points within a few times.
  CHECK_NOTHROW(StaticProblem(cantilever(arc(20, 0, 1.2), Section::circle(1.0), 100.0, Vec3(0, -0.01, 0), Vec3::Zero())));
  CHECK_NOTHROW(StaticProblem(cantilever(geometry::NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1, 1}, {Vec3(0, 0, 0), Vec3(1, 2, 0), Vec3(15, 1, 0), Vec3(20, 0, 0)}),
                                         Section::circle(1.0), 100.0, Vec3(0, -0.01, 0), Vec3::Zero())));
}

TEST_CASE("stiffness overrides no section can have are refused, naming the field", "[mechanics]") {
  // A torsion constant of 1e-300 mm^4 was "a mechanism (add supports)", a shear factor of 1e-300 a
  // Newton failure.
  const Design base = cantilever(straight(Vec3::Zero(), Vec3(20, 0, 0)), Section::circle(1.0), 100.0, Vec3(0, -0.01, 0), Vec3(0.01, 0, 0));
  for (const double torsion : {1e-300, 1e300}) {
    Design d = base;
    mechanics::RodMechanics over;
    over.rod = "beam", over.torsionConstant = torsion;
    d.mechanics.rods.push_back(over);
    CHECK_THROWS_WITH(StaticProblem(d), Catch::Contains("mechanics.rods.beam.torsion_constant: ") &&
                                            Catch::Contains("outside 1e-6 of the section's own (0.0981748 mm^4)"));
  }
  Design shear = base;
  shear.mechanics.shearFactor = 1e-300;
  CHECK_THROWS_WITH(StaticProblem(shear), Catch::Contains("mechanics.shear_factor: 1e-300 is outside 0.001 to 10"));
  Design fine = base;  // a thin-walled section's figures pass
  mechanics::RodMechanics over;
  over.rod = "beam", over.torsionConstant = 0.02, over.shearFactor = 0.4;
  fine.mechanics.rods.push_back(over);
  CHECK_NOTHROW(StaticProblem(fine));
}

TEST_CASE("loads no rod of the design bears are refused, naming the field", "[mechanics]") {
  // A force of 1e30 N ended in "Newton did not converge beyond load factor 0", naming nothing.
  const auto with = [](const Vec3& force, const Vec3& moment) {
    return cantilever(straight(Vec3::Zero(), Vec3(20, 0, 0)), Section::circle(1.0), 100.0, force, moment);
  };
  CHECK_THROWS_WITH(StaticProblem(with(Vec3(0, -1e30, 0), Vec3::Zero())), Catch::Contains("force: a force of 1e+30 N is more than"));
  CHECK_THROWS_WITH(StaticProblem(with(Vec3(0, -1e300, 0), Vec3::Zero())), Catch::Contains("a force of 1e+300 N"));
  CHECK_THROWS_WITH(StaticProblem(with(Vec3::Zero(), Vec3(0, 0, 1e30))), Catch::Contains("moment: a moment of 1e+30 N mm is more than"));
  Design moved = with(Vec3::Zero(), Vec3::Zero());
  moved.mechanics.supports[0].displacement = Vec3(1e9, 0, 0);
  CHECK_THROWS_WITH(StaticProblem(moved), Catch::Contains("displacement: a displacement of 1e+09 mm"));
  // E A of this rod is 78.5 N: 100 N bends it far, as designs may, and passes.
  CHECK_NOTHROW(StaticProblem(with(Vec3(0, -100, 0), Vec3(0, 0, 500))));
}
