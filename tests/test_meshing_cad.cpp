// rods-from-cad: STEP and IGES models written by OpenCASCADE, rods checked against the exact curves.
#include "meshing/meshing.hpp"
#include "tests/meshing/cad_fixtures.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <map>
#include <unistd.h>

namespace fs = std::filesystem;
using namespace rodfab;
using geometry::Vec3;

namespace {

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("rodfab-test-cad-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
}

Vec3 toVec(const gp_Pnt& p) { return {p.X(), p.Y(), p.Z()}; }

// Largest distance from the rod's centerline (sampled) to the exact curve over [first, last], found
// by sampling the exact curve densely and refining with the rod's own closest-point search the other way.
double largestDeviation(const geometry::Rod& rod, const Handle(Geom_Curve)& exact, double first, double last) {
  double largest = 0;
  for (int i = 0; i <= 400; ++i) {
    const Vec3 p = toVec(exact->Value(first + (last - first) * i / 400));
    largest = std::max(largest, rod.closestPoint(p).distance);
  }
  return largest;
}

}  // namespace

TEST_CASE("a box's STEP model: 12 straight rods meeting 3 by 3 at 8 joints", "[meshing][cad]") {
  testing::writeStep(testing::box(10, 20, 30), scratch("box.step"));
  const meshing::CadRods result = meshing::rodsFromCad(scratch("box.step"), {});
  REQUIRE(result.structure.rods.size() == 12);
  CHECK(result.report.edges == 12);
  CHECK(result.report.joints == 8);
  CHECK(result.report.largestEndMove < 1e-9);
  std::map<std::array<double, 3>, int> ends;
  for (const auto& rod : result.structure.rods) {
    const auto& c = rod.centerline();
    const Vec3 a = c.point(c.domainBegin()), b = c.point(c.domainEnd());
    for (const Vec3& p : {a, b}) {
      ++ends[{p.x(), p.y(), p.z()}];
      for (int k = 0; k < 3; ++k) CHECK((std::abs(p[k]) < 1e-9 || std::abs(p[k] - Vec3(10, 20, 30)[k]) < 1e-9));
    }
    // A box edge runs along one axis: straight, and as long as the box is in that direction.
    const Vec3 d = (b - a).cwiseAbs();
    CHECK(((d.x() > 9.99 && d.y() < 1e-9 && d.z() < 1e-9) || (d.y() > 19.99 && d.x() < 1e-9 && d.z() < 1e-9) ||
           (d.z() > 29.99 && d.x() < 1e-9 && d.y() < 1e-9)));
    for (int i = 0; i <= 10; ++i) {
      const double u = c.domainBegin() + (c.domainEnd() - c.domainBegin()) * i / 10;
      const Vec3 p = c.point(u), onLine = a + (b - a) * ((p - a).dot(b - a) / (b - a).squaredNorm());
      CHECK((p - onLine).norm() < 1e-9);
    }
  }
  REQUIRE(ends.size() == 8);
  for (const auto& [p, n] : ends) CHECK(n == 3);
}

TEST_CASE("a B-spline curve through IGES and STEP keeps its exact shape", "[meshing][cad]") {
  const Handle(Geom_BSplineCurve) spline = testing::testSpline();
  for (const std::string name : {"spline.igs", "spline.stp"}) {
    if (name.ends_with(".igs")) testing::writeIges(testing::edgeOf(spline), scratch(name));
    else testing::writeStep(testing::edgeOf(spline), scratch(name));
    const meshing::CadRods result = meshing::rodsFromCad(scratch(name), {});
    REQUIRE(result.structure.rods.size() == 1);
    const geometry::Rod& rod = result.structure.rods[0];
    CHECK(rod.centerline().degree() == 3);
    CHECK(rod.centerline().points().size() == 6);
    INFO(name);
    CHECK(largestDeviation(rod, spline, 0, 1) < 1e-7);
    CHECK(rod.length() == Approx(rod.centerline().arcLength()));
  }
}

TEST_CASE("a circle becomes an exact rational B-spline whose ends meet", "[meshing][cad]") {
  const Handle(Geom_Circle) circle = testing::testCircle();
  testing::writeStep(testing::edgeOf(circle), scratch("circle.step"));
  const meshing::CadRods result = meshing::rodsFromCad(scratch("circle.step"), {});
  REQUIRE(result.structure.rods.size() == 1);
  const auto& c = result.structure.rods[0].centerline();
  CHECK(c.isRational());
  const Vec3 centre(3, -2, 7), axis = Vec3(1, 1, 1).normalized();
  for (int i = 0; i <= 200; ++i) {
    const Vec3 p = c.point(c.domainBegin() + (c.domainEnd() - c.domainBegin()) * i / 200);
    CHECK((p - centre).norm() == Approx(5.0).margin(1e-9));
    CHECK(std::abs((p - centre).dot(axis)) < 1e-9);
  }
  CHECK(c.arcLength() == Approx(2 * M_PI * 5).epsilon(1e-9));
  CHECK(c.points().front() == c.points().back());  // one joint: the ends merged bit for bit
  CHECK(result.report.joints == 1);
  CHECK(largestDeviation(result.structure.rods[0], circle, 0, 2 * M_PI) < 1e-9);
}

TEST_CASE("CAD errors name the file and the problem", "[meshing][cad]") {
  const auto error = [](const fs::path& file) -> std::string {
    try {
      meshing::rodsFromCad(file, {});
    } catch (const meshing::MeshError& e) {
      CHECK(std::string(e.what()).rfind(file.string() + ": ", 0) == 0);
      return e.what();
    }
    return "no error";
  };
  std::ofstream(scratch("junk.step")) << "this is not ISO-10303-21\n";
  CHECK_THAT(error(scratch("junk.step")), Catch::Contains("not a readable STEP file"));
  std::ofstream(scratch("junk.iges")) << "nope\n";
  CHECK_THAT(error(scratch("junk.iges")), Catch::Contains("not a readable IGES file"));
  CHECK_THAT(error(scratch("model.dwg")), Catch::Contains("unknown CAD format"));
  CHECK_THAT(error(scratch("missing.step")), Catch::Contains("no such file"));
}
