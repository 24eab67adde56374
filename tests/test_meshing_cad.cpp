// rods-from-cad: STEP and IGES models written by OpenCASCADE, rods checked against the exact curves.
#include "meshing/cad_reader.hpp"
#include "meshing/meshing.hpp"
#include "tests/meshing/cad_fixtures.hpp"
#include "tests/temp_dir.hpp"

#include <BRep_Builder.hxx>
#include <GeomAPI_ProjectPointOnCurve.hxx>
#include <GeomConvert.hxx>
#include <Geom_OffsetCurve.hxx>
#include <Geom_TrimmedCurve.hxx>
#include <TopoDS_Compound.hxx>

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <cmath>
#include <cstring>
#include <map>
#include <unistd.h>

namespace fs = std::filesystem;
using namespace rodfab;
using geometry::Vec3;

namespace {

fs::path scratch(const std::string& name) { return rodfab::test::processScratch("cad", name); }

// What `read` throws as a MeshError (which must start with "FILE: "), or "no error".
template <class Read>
std::string meshErrorOf(const fs::path& file, Read read) {
  try {
    read();
  } catch (const meshing::MeshError& e) {
    CHECK(std::string(e.what()).rfind(file.string() + ": ", 0) == 0);
    return e.what();
  }
  return "no error";
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

namespace {

// An arc of radius 5e8 mm over 6 radians as a B-spline of 100 knot spans.
Handle(Geom_BSplineCurve) hugeArc(double z) {
  const Handle(Geom_Circle) circle = new Geom_Circle(gp_Ax2(gp_Pnt(0, 0, z), gp_Dir(0, 0, 1)), 5e8);
  Handle(Geom_BSplineCurve) arc = GeomConvert::CurveToBSplineCurve(new Geom_TrimmedCurve(circle, 0.0, 6.0));
  const double a = arc->FirstParameter(), b = arc->LastParameter();
  for (int i = 1; i < 100; ++i) arc->InsertKnot(a + (b - a) * i / 100);
  return arc;
}

}  // namespace

TEST_CASE("a curve too intricate to sample at its section's tolerance is refused, naming the first such edge", "[meshing][cad]") {
  // A chord of an arc of radius R strays by R theta^2 / 8: followed within a 0.01 mm rod's 1e-4 mm, a
  // 5e8 mm arc needs a sample every 4e-6 rad, 1.5 million over 6 rad, above geometry::kMaxSamplesPerRod.
  // Two of them after a small circle: the rods are checked on both cores, the first in the model's
  // order is the one named.
  TopoDS_Compound model;
  BRep_Builder builder;
  builder.MakeCompound(model);
  builder.Add(model, testing::edgeOf(testing::testCircle()));
  for (double z : {0.0, 1.0}) builder.Add(model, testing::edgeOf(hugeArc(z)));
  testing::writeStep(model, scratch("huge-arcs.step"));
  meshing::CadRodOptions options;
  options.section = geometry::Section::circle(0.01);
  const std::string message = meshErrorOf(scratch("huge-arcs.step"), [&] { meshing::rodsFromCad(scratch("huge-arcs.step"), options); });
  CHECK_THAT(message, Catch::Contains("huge-arcs.step: edge 1") && Catch::Contains("polyline samples"));
  CHECK_THAT(message, !Catch::Contains("edge 2"));
  options.section = geometry::Section::circle(1.0);  // within 0.01 mm: 150,000 samples each
  CHECK(meshing::rodsFromCad(scratch("huge-arcs.step"), options).structure.rods.size() == 3);
}

namespace {

// Largest distance from 401 points of the rod's centerline to the exact curve (OpenCASCADE's projection).
double largestDeviationFromRod(const geometry::Rod& rod, const Handle(Geom_Curve)& exact) {
  const geometry::NurbsCurve& c = rod.centerline();
  double largest = 0;
  for (int i = 0; i <= 400; ++i) {
    const Vec3 p = c.point(c.domainBegin() + (c.domainEnd() - c.domainBegin()) * i / 400);
    GeomAPI_ProjectPointOnCurve projection(gp_Pnt(p.x(), p.y(), p.z()), exact);
    largest = std::max(largest, projection.LowerDistance());
  }
  return largest;
}

Handle(Geom_BSplineCurve) bezier(const std::vector<gp_Pnt>& points) {
  TColgp_Array1OfPnt poles(1, static_cast<int>(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i) poles(static_cast<int>(i) + 1) = points[i];
  TColStd_Array1OfReal knots(1, 2);
  knots(1) = 0, knots(2) = 1;
  TColStd_Array1OfInteger mults(1, 2);
  mults(1) = mults(2) = static_cast<int>(points.size());
  return new Geom_BSplineCurve(poles, knots, mults, static_cast<int>(points.size()) - 1);
}

}  // namespace

TEST_CASE("CAD errors name the file and the problem", "[meshing][cad]") {
  const auto error = [](const fs::path& file) { return meshErrorOf(file, [&] { meshing::rodsFromCad(file, {}); }); };
  std::ofstream(scratch("junk.step")) << "this is not ISO-10303-21\n";
  CHECK_THAT(error(scratch("junk.step")), Catch::Contains("not a readable STEP file"));
  std::ofstream(scratch("junk.iges")) << "nope\n";
  CHECK_THAT(error(scratch("junk.iges")), Catch::Contains("not a readable IGES file"));
  CHECK_THAT(error(scratch("model.dwg")), Catch::Contains("unknown CAD format"));
  CHECK_THAT(error(scratch("missing.step")), Catch::Contains("no such file"));
}

namespace {

// A STEP model written as OpenCASCADE writes a wireframe: the product and context entities, a curve
// set #15 of the curve #16, the entities `data` gives (#15 onwards) and the length unit #27.
std::string stepModel(const std::string& data, const std::string& unit = "( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) )") {
  return "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('test'),'2;1');\nFILE_NAME('t','2026-12-04T00:00:00',(''),(''),'','','');\n"
         "FILE_SCHEMA(('AUTOMOTIVE_DESIGN { 1 0 10303 214 1 1 1 1 }'));\nENDSEC;\nDATA;\n"
         "#1 = APPLICATION_PROTOCOL_DEFINITION('international standard','automotive_design',2000,#2);\n"
         "#2 = APPLICATION_CONTEXT('core data for automotive mechanical design processes');\n"
         "#3 = SHAPE_DEFINITION_REPRESENTATION(#4,#10);\n#4 = PRODUCT_DEFINITION_SHAPE('','',#5);\n"
         "#5 = PRODUCT_DEFINITION('design','',#6,#9);\n#6 = PRODUCT_DEFINITION_FORMATION('','',#7);\n"
         "#7 = PRODUCT('p','p','',(#8));\n#8 = PRODUCT_CONTEXT('',#2,'mechanical');\n"
         "#9 = PRODUCT_DEFINITION_CONTEXT('part definition',#2,'design');\n"
         "#10 = GEOMETRICALLY_BOUNDED_WIREFRAME_SHAPE_REPRESENTATION('',(#11,#15),#26);\n"
         "#11 = AXIS2_PLACEMENT_3D('',#12,#13,#14);\n#12 = CARTESIAN_POINT('',(0.,0.,0.));\n"
         "#13 = DIRECTION('',(0.,0.,1.));\n#14 = DIRECTION('',(1.,0.,0.));\n" + data +
         "#26 = ( GEOMETRIC_REPRESENTATION_CONTEXT(3) GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT((#30)) "
         "GLOBAL_UNIT_ASSIGNED_CONTEXT((#27,#28,#29)) REPRESENTATION_CONTEXT('c','3D') );\n"
         "#27 = " + unit + ";\n#28 = ( NAMED_UNIT(*) PLANE_ANGLE_UNIT() SI_UNIT($,.RADIAN.) );\n"
         "#29 = ( NAMED_UNIT(*) SI_UNIT($,.STERADIAN.) SOLID_ANGLE_UNIT() );\n"
         "#30 = UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E-07),#27,'distance_accuracy_value','');\n"
         "ENDSEC;\nEND-ISO-10303-21;\n";
}

// The curve set #15 holding a cubic B-spline #17 (trimmed by #16) through control points #18 to #23;
// `points` replaces the list of the spline's control points, `degree` its degree.
std::string splineData(const std::string& points = "(#18,#19,#20,#21,#22,#23)", const std::string& degree = "3",
                       const std::string& set = "(#16)", const std::string& x19 = "10.") {
  return "#15 = GEOMETRIC_CURVE_SET(''," + set + ");\n"
         "#16 = TRIMMED_CURVE('',#17,(#24,PARAMETER_VALUE(0.)),(#25,PARAMETER_VALUE(1.)),.T.,.PARAMETER.);\n"
         "#17 = B_SPLINE_CURVE_WITH_KNOTS(''," + degree + "," + points +
         ",.UNSPECIFIED.,.F.,.F.,(4,1,1,4),(0.,0.3,0.45,1.),.UNSPECIFIED.);\n"
         "#18 = CARTESIAN_POINT('',(0.,0.,0.));\n#19 = CARTESIAN_POINT('',(" + x19 + ",5.,2.));\n"
         "#20 = CARTESIAN_POINT('',(20.,-5.,6.));\n#21 = CARTESIAN_POINT('',(30.,8.,1.));\n"
         "#22 = CARTESIAN_POINT('',(38.,0.,-4.));\n#23 = CARTESIAN_POINT('',(45.,3.,0.));\n"
         "#24 = CARTESIAN_POINT('',(0.,0.,0.));\n#25 = CARTESIAN_POINT('',(45.,3.,0.));\n";
}

// A circle of `radius` about #19, trimmed to its full turn.
std::string circleData(const std::string& radius) {
  return "#15 = GEOMETRIC_CURVE_SET('',(#16));\n"
         "#16 = TRIMMED_CURVE('',#17,(PARAMETER_VALUE(0.)),(PARAMETER_VALUE(6.28318530718)),.T.,.PARAMETER.);\n"
         "#17 = CIRCLE('',#18," + radius + ");\n#18 = AXIS2_PLACEMENT_3D('',#19,#13,#14);\n"
         "#19 = CARTESIAN_POINT('',(3.,-2.,7.));\n";
}

// The message of the MeshError that reading `text` as `name` gives (checked to start with the file).
std::string cadError(const std::string& name, const std::string& text, const meshing::CadRodOptions& options = {}) {
  const fs::path file = scratch(name);
  std::ofstream(file, std::ios::binary) << text;
  return meshErrorOf(file, [&] { meshing::rodsFromCad(file, options); });
}

}  // namespace

TEST_CASE("an offset curve and a degree-9 spline become degree-7 rods within the approximation tolerance", "[meshing][cad]") {
  // OpenCASCADE's exact B-splines of these are of degree 14 (the 2 mm offset, in its plane, of a planar
  // cubic; its STEP writer does not write offset curves, so the model is text) and 9 (a Bezier of 10
  // control points, as some CAD systems write).
  const std::vector<gp_Pnt> cubic = {{0, 0, 0}, {10, 5, 0}, {20, -5, 0}, {30, 0, 0}};
  std::vector<gp_Pnt> wavy;
  for (int i = 0; i <= 9; ++i) wavy.emplace_back(3.0 * i, 4.0 * std::sin(i), 2.0 * std::cos(i));
  std::string data = "#15 = GEOMETRIC_CURVE_SET('',(#16,#40));\n#16 = OFFSET_CURVE_3D('',#17,2.,.F.,#13);\n"
                     "#17 = B_SPLINE_CURVE_WITH_KNOTS('',3,(#18,#19,#20,#21),.UNSPECIFIED.,.F.,.F.,(4,4),(0.,1.),.UNSPECIFIED.);\n"
                     "#40 = B_SPLINE_CURVE_WITH_KNOTS('',9,(#41,#42,#43,#44,#45,#46,#47,#48,#49,#50),.UNSPECIFIED.,.F.,.F.,"
                     "(10,10),(0.,1.),.UNSPECIFIED.);\n";
  const auto point = [](int id, const gp_Pnt& p) {
    char text[160];
    std::snprintf(text, sizeof text, "#%d = CARTESIAN_POINT('',(%.17g,%.17g,%.17g));\n", id, p.X(), p.Y(), p.Z());
    return std::string(text);
  };
  for (int i = 0; i < 4; ++i) data += point(18 + i, cubic[i]);
  for (int i = 0; i < 10; ++i) data += point(41 + i, wavy[i]);
  const fs::path file = scratch("high-degree.step");
  std::ofstream(file) << stepModel(data);
  const meshing::CadRods result = meshing::rodsFromCad(file, {});
  REQUIRE(result.structure.rods.size() == 2);
  CHECK(result.report.approximated == 2);
  CHECK(result.report.largestApproximationError > 0);
  CHECK(result.report.largestApproximationError <= meshing::kCadApproximationToleranceMm);
  // The rod is checked against the exact offset: OpenCASCADE reads the STEP offset as -2 mm along
  // tangent x ref_direction (Geom_OffsetCurve's side), i.e. 2 mm along ref_direction x tangent.
  const Handle(Geom_Curve) exact[] = {new Geom_OffsetCurve(bezier(cubic), -2.0, gp_Dir(0, 0, 1)), bezier(wavy)};
  for (int r = 0; r < 2; ++r) {
    const geometry::Rod& rod = result.structure.rods[r];
    CHECK(rod.centerline().degree() <= geometry::kMaxDegree);
    CHECK(largestDeviation(rod, exact[r], 0, 1) <= meshing::kCadApproximationToleranceMm);
    CHECK(largestDeviationFromRod(rod, exact[r]) <= meshing::kCadApproximationToleranceMm);
    const geometry::NurbsCurve& c = rod.centerline();
    CHECK((c.point(c.domainBegin()) - toVec(exact[r]->Value(0))).norm() <= meshing::kCadApproximationToleranceMm);
    CHECK((c.point(c.domainEnd()) - toVec(exact[r]->Value(1))).norm() <= meshing::kCadApproximationToleranceMm);
  }
}

TEST_CASE("a high-degree curve with more kinks than the approximation may have pieces is refused, naming it", "[meshing][cad]") {
  // Degree 8, a kink at each of 2,400 knots: a piece of the approximation cannot straddle a kink, and
  // at most kMaxSplineControls / kMaxDegree = 2,340 pieces are allowed.
  constexpr int kSpans = 2400, kDegree = 8;
  std::string points, mults = "(9", knots = "(0.";
  std::string entities;
  for (int k = 0; k <= kDegree * kSpans; ++k) {
    char line[96];
    std::snprintf(line, sizeof line, "#%d = CARTESIAN_POINT('',(%.2f,%s,0.));\n", 1000 + k, 0.01 * k, k % 2 ? "0.5" : "0.");
    entities += line;
    std::snprintf(line, sizeof line, "%s#%d", k ? "," : "(", 1000 + k);
    points += line;
  }
  for (int s = 1; s <= kSpans; ++s) {
    char knot[24];
    std::snprintf(knot, sizeof knot, ",%d.", s);
    mults += s < kSpans ? ",8" : ",9";
    knots += knot;
  }
  const std::string data = "#15 = GEOMETRIC_CURVE_SET('',(#16));\n#16 = B_SPLINE_CURVE_WITH_KNOTS('',8," + points +
                           "),.UNSPECIFIED.,.F.,.F.," + mults + ")," + knots + "),.UNSPECIFIED.);\n" + entities;
  CHECK_THAT(cadError("kinks.step", stepModel(data)),
             Catch::Contains("kinks.step: edge 0 (entity #16 (B_SPLINE_CURVE_WITH_KNOTS)): a curve of degree 8, above the 7") &&
                 Catch::Contains("cannot be approximated within 1e-05 mm by 2340 pieces"));
}

TEST_CASE("the hostile-file fixture reads as a valid spline", "[meshing][cad][hostile]") {
  const fs::path file = scratch("fixture.step");
  std::ofstream(file) << stepModel(splineData());
  const meshing::CadRods result = meshing::rodsFromCad(file, {});
  REQUIRE(result.structure.rods.size() == 1);
  CHECK(result.structure.rods[0].centerline().degree() == 3);
}

TEST_CASE("STEP files OpenCASCADE would crash on are refused, naming the entity or line", "[meshing][cad][hostile]") {
  using Catch::Contains;
  // Failures OpenCASCADE records while loading: the transfer would follow the null handles they leave.
  CHECK_THAT(cadError("missing.step", stepModel(splineData("(#9999,#19,#20,#21,#22,#23)"))),
             Contains("malformed: entity #17 (B_SPLINE_CURVE_WITH_KNOTS)") && Contains("unresolved"));
  CHECK_THAT(cadError("noargs.step", stepModel(splineData() + "#31 = B_SPLINE_CURVE_WITH_KNOTS();\n"
                                                              "#32 = GEOMETRIC_CURVE_SET('',(#31));\n")),
             Contains("entity #31 (B_SPLINE_CURVE_WITH_KNOTS)") && Contains("Count of Parameters"));
  CHECK_THAT(cadError("wrongtype.step", stepModel(splineData("(#13,#19,#20,#21,#22,#23)"))),
             Contains("entity #17 (B_SPLINE_CURVE_WITH_KNOTS)") && Contains("illegal type"));
  CHECK_THAT(cadError("selfref.step", stepModel(splineData("(#17,#19,#20,#21,#22,#23)"))), Contains("entity #17"));
  // A reference cycle: the transfer recursed until the stack ran out.
  CHECK_THAT(cadError("cycle.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "3", "(#15)"))),
             Contains("entity #15 (GEOMETRIC_CURVE_SET) refers to itself"));
  CHECK_THAT(cadError("cycle2.step", stepModel(splineData() + "#31 = GEOMETRIC_CURVE_SET('',(#16,#32));\n"
                                                              "#32 = GEOMETRIC_CURVE_SET('',(#31));\n")),
             Contains("refers to itself"));
  // Degrees and pole counts Geom_BSplineCurve refuses, checked before the converters index by them.
  CHECK_THAT(cadError("degree.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "30"))),
             Contains("B-spline entity #17 (B_SPLINE_CURVE_WITH_KNOTS): degree 30, expected 1 to 25"));
  CHECK_THAT(cadError("poles.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "9"))),
             Contains("6 control points, expected at least degree + 1 = 10"));
  // What the parser itself cannot take, found in the text.
  const std::string deep = std::string(100'000, '(') + std::string(100'000, ')');
  CHECK_THAT(cadError("deep.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "3", "(#16," + deep + ")"))),
             Contains("line 22: lists nested deeper than 64 levels"));
  CHECK_THAT(cadError("hugeid.step", stepModel(splineData("(#18,#99999999999999999999,#20,#21,#22,#23)"))),
             Contains("line 24: an entity id above 999999999"));
  std::string longList = "(#16";
  for (int i = 0; i < 100'000; ++i) longList += ",#16";
  CHECK_THAT(cadError("longlist.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "3", longList + ")"))),
             Contains("line 22: a list of more than 100000 elements"));
  // Empty lists where STEP requires elements: OpenCASCADE's load check and transfer crash on them. An
  // entity without parameters (every file's LENGTH_UNIT()) is not such a list.
  std::string noKnots = splineData();
  noKnots.replace(noKnots.find("(0.,0.3,0.45,1.)"), 16, "( )");
  CHECK_THAT(cadError("noknots.step", stepModel(noKnots)), Contains("line 24: an empty list in a B_SPLINE_CURVE_WITH_KNOTS"));
  std::string noDirection = stepModel(splineData());
  noDirection.replace(noDirection.find("DIRECTION('',(0.,0.,1.))"), 24, "DIRECTION('',())");
  CHECK_THAT(cadError("nodirection.step", noDirection), Contains("an empty list in a DIRECTION, where STEP requires at least one"));
  // Text in strings and comments is not counted.
  const std::string hostile = "#99999999999999999999 " + std::string(100, '(');
  std::string named = splineData();
  named.replace(named.find("''"), 2, "'" + hostile + "'");
  const fs::path quoted = scratch("quoted.step");
  std::ofstream(quoted) << stepModel("/* " + hostile + " */\n" + named);
  CHECK(meshing::rodsFromCad(quoted, {}).structure.rods.size() == 1);
}

TEST_CASE("an IGES B-spline of an impossible degree is refused before OpenCASCADE loads it", "[meshing][cad][hostile]") {
  const fs::path valid = scratch("valid.igs");
  testing::writeIges(testing::edgeOf(testing::testSpline()), valid);
  std::ifstream in(valid);
  std::string text, line;
  bool changed = false;
  while (std::getline(in, line)) {
    // The parameter record "126,5,3,..." (upper index 5, degree 3): the degree becomes 1000000; six
    // weights written as integers make room for it in the record's 64 data columns.
    if (!changed && line.rfind("126,5,3,", 0) == 0) {
      std::string data = line.substr(0, 64);
      const std::size_t weights = data.find("1.,1.,1.,1.,1.,1.,");
      REQUIRE(weights != std::string::npos);
      data.replace(weights, 18, "1,1,1,1,1,1,");
      data.replace(0, 8, "126,5,1000000,");
      REQUIRE(data.size() == 64);
      line = data + line.substr(64);
      changed = true;
    }
    text += line + "\n";
  }
  REQUIRE(changed);
  CHECK_THAT(cadError("degree.igs", text),
             Catch::Contains("malformed IGES B-spline curve (type 126): degree 1000000, expected 1 to 25"));
}

TEST_CASE("rods-from-cad never builds a design that validate refuses", "[meshing][cad][hostile]") {
  using Catch::Contains;
  // Coordinates beyond +-1e9 mm, each named by its edge and the entity it came from.
  CHECK_THAT(cadError("far.step", stepModel(splineData("(#18,#19,#20,#21,#22,#23)", "3", "(#16)", "1.E12"))),
             Contains("edge 0 (entity #16 (TRIMMED_CURVE)): a control point at (1e+12, 5, 2) mm, beyond the +-1e9 mm"));
  CHECK_THAT(cadError("line.step", stepModel("#15 = GEOMETRIC_CURVE_SET('',(#16));\n#16 = LINE('',#12,#17);\n"
                                             "#17 = VECTOR('',#13,1.);\n")),
             Contains("edge 0 (entity #16 (LINE)): a control point at (0, 0, -2e+100) mm"));
  const std::string huge = cadError("circle.step", stepModel(circleData("1.E300")));
  CHECK_THAT(huge, Contains("beyond the +-1e9 mm"));
  CHECK(huge.size() < 300);  // numbers in a short format, not 300 digits
  CHECK_THAT(cadError("unit.step", stepModel(splineData(), "( CONVERSION_BASED_UNIT('BIG',#40) LENGTH_UNIT() NAMED_UNIT(#41) );\n"
                                             "#40 = LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E300),#42);\n"
                                             "#41 = DIMENSIONAL_EXPONENTS(1.,0.,0.,0.,0.,0.,0.);\n"
                                             "#42 = ( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) )")),
             Contains("beyond the +-1e9 mm"));
  // Zero-length centerlines, found by the design file's own checks.
  const std::string zero = "degenerate centerline: its length is zero";
  CHECK_THAT(cadError("r0.step", stepModel(circleData("0."))), Contains("edge 0 (entity #16 (TRIMMED_CURVE)): " + zero));
  // Checked before the rod's frame is built on it (a zero tangent has no normal).
  meshing::CadRodOptions ellipse;
  ellipse.section = geometry::Section::ellipse(1, 2);
  CHECK_THAT(cadError("r0e.step", stepModel(circleData("0.")), ellipse), Contains("edge 0 (entity #16 (TRIMMED_CURVE)): " + zero));
  // A line 0.0005 mm long: both its ends merge onto one point (joint tolerance 0.001 mm).
  CHECK_THAT(cadError("short.step", stepModel("#15 = GEOMETRIC_CURVE_SET('',(#16));\n"
                                              "#16 = TRIMMED_CURVE('',#17,(PARAMETER_VALUE(0.)),(PARAMETER_VALUE(0.0005)),"
                                              ".T.,.PARAMETER.);\n"
                                              "#17 = LINE('',#12,#18);\n#18 = VECTOR('',#14,1.);\n")),
             Contains("edge 0 (entity #16 (TRIMMED_CURVE)): " + zero));
  std::string same = splineData();
  for (const char* p : {"0.,0.,0.", "10.,5.,2.", "20.,-5.,6.", "30.,8.,1.", "38.,0.,-4.", "45.,3.,0."})
    for (std::size_t at; (at = same.find(p)) != std::string::npos;) same.replace(at, std::strlen(p), "1.,1.,1.");
  CHECK_THAT(cadError("same.step", stepModel(same)), Contains(zero));
  CHECK_THAT(cadError("unit0.step", stepModel(splineData(), "( CONVERSION_BASED_UNIT('ZERO',#40) LENGTH_UNIT() NAMED_UNIT(#41) );\n"
                                              "#40 = LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(0.),#42);\n"
                                              "#41 = DIMENSIONAL_EXPONENTS(1.,0.,0.,0.,0.,0.,0.);\n"
                                              "#42 = ( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) )")),
             Contains(zero));
}

namespace {

// A stand-in for rodfab-cad-reader: a shell script with `body`, made executable.
fs::path fakeReader(const std::string& name, const std::string& body) {
  const fs::path path = scratch(name);
  std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
  fs::permissions(path, fs::perms::owner_all);
  return path;
}

std::string errorThrough(const fs::path& helper, const fs::path& model) {
  return meshErrorOf(model, [&] { meshing::detail::rodsFromCadThrough(helper, model, {}); });
}

}  // namespace

TEST_CASE("whatever becomes of the CAD reader process is an error naming the file", "[meshing][cad][hostile]") {
  using Catch::Contains;
  const fs::path model = scratch("stand-in.step");
  std::ofstream(model) << "ISO-10303-21;\n";
  CHECK_THAT(errorThrough(fakeReader("segv.sh", "kill -SEGV $$"), model),
             Contains("the CAD reader (OpenCASCADE) crashed on this file (signal 11"));
  CHECK_THAT(errorThrough(fakeReader("abort.sh", "echo 'terminate called' >&2; kill -ABRT $$"), model),
             Contains("(signal 6") && Contains("(it said: terminate called)"));
  CHECK_THAT(errorThrough(fakeReader("exit3.sh", "echo boom >&2; exit 3"), model),
             Contains("stopped with exit code 3 and no answer (it said: boom)"));
  CHECK(errorThrough(fakeReader("error.sh", "printf '{\"error\": \"edge 2: a curve of degree 9\"}' >&3"), model) ==
        model.string() + ": edge 2: a curve of degree 9");
  CHECK_THAT(errorThrough(fakeReader("garbage.sh", "echo 'not json' >&3"), model), Contains("answer is not JSON"));
  CHECK_THAT(errorThrough(fakeReader("half.sh", "printf '{\"design\": {' >&3; kill -KILL $$"), model),
             Contains("the CAD reader was killed (signal 9, Killed), not by rodfab: the system may have run out of memory"));
  CHECK_THAT(errorThrough(fakeReader("nodesign.sh", "echo '{\"report\": {}}' >&3"), model), Contains("has no design and report"));
  CHECK_THAT(errorThrough(fakeReader("baddesign.sh",
                                     "echo '{\"design\": {\"format\": \"rodfab.design/1\", \"rods\": 7}, \"report\": {}}' >&3"),
                          model),
             Contains("the CAD reader's design is not valid"));
  CHECK_THAT(errorThrough(scratch("no-such-reader"), model), Contains("did not start (No such file or directory)"));
  // A reader that never answers is waited for, not polled to death: the answer comes when it exits.
  CHECK_THAT(errorThrough(fakeReader("slow.sh", "sleep 0.3; exit 0"), model), Contains("answer is not JSON"));
}

TEST_CASE("the CAD reader's arguments carry the options exactly", "[meshing][cad]") {
  meshing::detail::CadReaderRequest request{"a b/c.step", {}, 123456789012345ULL, 4194304};
  request.options.section = geometry::Section::ellipse(0.1, 1.0 / 3.0);
  request.options.caps = geometry::CapStyle::Flat;
  request.options.modulusMpa = 2.0 / 7.0;
  request.options.jointTolerance = 1e-9 * 3.0;
  const meshing::detail::CadReaderRequest back = meshing::detail::fromReaderArguments(meshing::detail::readerArguments(request));
  CHECK(back.file == request.file);
  CHECK(back.options.section.shape == geometry::SectionShape::Ellipse);
  CHECK(back.options.section.width == 0.1);
  CHECK(back.options.section.height == 1.0 / 3.0);
  CHECK(back.options.caps == geometry::CapStyle::Flat);
  CHECK(back.options.modulusMpa == 2.0 / 7.0);
  CHECK(back.options.jointTolerance == 1e-9 * 3.0);
  CHECK(back.memoryBudget == request.memoryBudget);
  CHECK(back.parentProcess == 4194304);
  std::vector<std::string> wrong = meshing::detail::readerArguments(request);
  wrong[1] = "hexagon";
  CHECK_THROWS_AS(meshing::detail::fromReaderArguments(wrong), std::invalid_argument);
  wrong.pop_back();
  CHECK_THROWS_AS(meshing::detail::fromReaderArguments(wrong), std::invalid_argument);
}

TEST_CASE("an IGES loop whose edge index is past its edge list is refused, naming the loop", "[meshing][cad][hostile]") {
  // A box in IGES's B-rep form: its loops (type 508) refer to the edge list (504) by index, read
  // unchecked by OpenCASCADE's transfer (a SIGSEGV for an index past the list, found by mutate_cad.py).
  const fs::path valid = scratch("box.igs"), bad = scratch("badloop.igs");
  testing::writeIges(testing::box(10, 20, 30), valid);
  std::ifstream in(valid);
  std::string text, line;
  bool changed = false;
  while (std::getline(in, line)) {
    if (!changed && line.rfind("508,", 0) == 0) {  // 508,N,TYPE,EDGE LIST,INDEX,...: the first edge's index becomes 99
      std::string data = line.substr(0, 64);
      const std::size_t at = data.find(',', data.find(',', data.find(',', data.find(',') + 1) + 1) + 1) + 1;
      const std::size_t end = data.find(',', at);
      data.replace(at, end - at, "99");
      while (data.size() > 64 && data.back() == ' ') data.pop_back();
      REQUIRE(data.size() <= 64);
      line = data + std::string(64 - data.size(), ' ') + line.substr(64);
      changed = true;
    }
    text += line + "\n";
  }
  REQUIRE(changed);
  std::ofstream(bad) << text;
  CHECK_THAT(meshErrorOf(bad, [&] { meshing::rodsFromCad(bad, {}); }),
             Catch::Contains("malformed: entity D") && Catch::Contains("Loop): edge 1 refers to item 99 of a list of 12"));
  CHECK(meshing::rodsFromCad(valid, {}).structure.rods.size() == 12);
}

TEST_CASE("a truncated IGES file, on which OpenCASCADE's reader crashes, is refused as cut short", "[meshing][cad][hostile]") {
  const fs::path whole = scratch("whole.igs"), cut = scratch("cut.igs");
  testing::writeIges(testing::edgeOf(testing::testSpline()), whole);
  std::ifstream in(whole, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Cut inside the B-spline's parameter records (the second of them), as an interrupted copy would.
  const std::size_t second = text.find("P0000002");
  REQUIRE(second != std::string::npos);
  std::ofstream(cut, std::ios::binary) << text.substr(0, second - 30);
  CHECK_THAT(meshErrorOf(cut, [&] { meshing::rodsFromCad(cut, {}); }), Catch::Contains("without IGES's Terminate record") &&
                                                                         Catch::Contains("cut short"));
  CHECK(meshing::rodsFromCad(whole, {}).structure.rods.size() == 1);
}
