// rods-from-cad: STEP and IGES models written by OpenCASCADE, rods checked against the exact curves.
// The hostile files and the reader process's failures: test_meshing_cad_hostile.cpp.
#include "geometry/design_file.hpp"
#include "meshing/cad_reader.hpp"
#include "meshing/meshing.hpp"
#include "tests/meshing/cad_test_support.hpp"

#include <BRep_Builder.hxx>
#include <GeomAPI_ProjectPointOnCurve.hxx>
#include <GeomConvert.hxx>
#include <Geom_OffsetCurve.hxx>
#include <Geom_TrimmedCurve.hxx>
#include <TopoDS_Compound.hxx>

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

using namespace rodfab;
using namespace rodfab::cad_test;

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
  // A circle bends by its radius everywhere: the report's smallest bend radius is 5 mm.
  CHECK(result.report.smallestBendRadius == Approx(5.0).epsilon(1e-9));
  CHECK(result.report.rodsBentTighterThanSection == 0);
  meshing::CadRodOptions thick;
  thick.section = geometry::Section::circle(10.2);  // radius 5.1 > 5
  CHECK(meshing::rodsFromCad(scratch("circle.step"), thick).report.rodsBentTighterThanSection == 1);
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

TEST_CASE("writeDesignFromCad writes the file writeDesign writes of rodsFromCad's rods, and says what summarize says", "[meshing][cad]") {
  testing::writeStep(testing::box(10, 20, 30), scratch("box-written.step"));
  const auto bytesOf = [](const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  meshing::CadRodOptions ellipses;
  ellipses.section = geometry::Section::ellipse(1.0, 0.6), ellipses.caps = geometry::CapStyle::Flat, ellipses.modulusMpa = 42.5;
  // The box with other options, the seeds' wireframe (lines, conics, splines, an offset curve) and
  // their high-degree curves (approximated).
  for (const auto& [model, options] : std::vector<std::pair<fs::path, meshing::CadRodOptions>>{
           {scratch("box-written.step"), ellipses}, {"tests/fuzz/seeds/cad/wireframe.step", {}}, {"tests/fuzz/seeds/cad/high-degree.step", {}}}) {
    INFO(model);
    const meshing::CadRods kept = meshing::rodsFromCad(model, options);
    geometry::writeDesign(kept.structure, scratch("kept.json"), "rods from the model");
    const meshing::CadDesignWritten written = meshing::writeDesignFromCad(model, options, scratch("written.json"), "rods from the model");
    CHECK(bytesOf(scratch("written.json")) == bytesOf(scratch("kept.json")));
    CHECK(geometry::isDesignRodfabWrote(scratch("written.json")));
    const geometry::DesignSummary s = geometry::summarize(kept.structure);
    CHECK(written.summary.rodCount == s.rodCount);
    CHECK(written.summary.totalLength == s.totalLength);
    CHECK((written.summary.bounds.min() == s.bounds.min() && written.summary.bounds.max() == s.bounds.max()));
    CHECK((written.report.rods == kept.report.rods && written.report.joints == kept.report.joints &&
           written.report.approximated == kept.report.approximated));
  }
  // A model the reader refuses: nothing written.
  std::ofstream(scratch("not-cad.step")) << "ISO-10303-21;\nnonsense\n";
  CHECK_THROWS_AS(meshing::writeDesignFromCad(scratch("not-cad.step"), {}, scratch("refused.json"), ""), meshing::MeshError);
  CHECK_FALSE(fs::exists(scratch("refused.json")));
}

TEST_CASE("entities OpenCASCADE cannot convert are counted and named, not dropped silently", "[meshing][cad]") {
  // Curve set #15 holds the 2 mm offset of a cubic whose end derivatives vanish (OpenCASCADE's transfer
  // throws converting it and drops the whole set); set #50 holds a plain cubic.
  const std::string data = "#15 = GEOMETRIC_CURVE_SET('',(#16));\n#16 = OFFSET_CURVE_3D('',#17,2.,.F.,#13);\n"
                           "#17 = B_SPLINE_CURVE_WITH_KNOTS('',3,(#18,#19,#20,#21),.UNSPECIFIED.,.F.,.F.,(4,4),(0.,1.),.UNSPECIFIED.);\n"
                           "#18 = CARTESIAN_POINT('',(0.,0.,0.));\n#19 = CARTESIAN_POINT('',(0.,0.,0.));\n"
                           "#20 = CARTESIAN_POINT('',(30.,0.,0.));\n#21 = CARTESIAN_POINT('',(30.,0.,0.));\n";
  const std::string plain = "#50 = GEOMETRIC_CURVE_SET('',(#40));\n"
                            "#40 = B_SPLINE_CURVE_WITH_KNOTS('',3,(#41,#42,#43,#44),.UNSPECIFIED.,.F.,.F.,(4,4),(0.,1.),.UNSPECIFIED.);\n"
                            "#41 = CARTESIAN_POINT('',(0.,10.,0.));\n#42 = CARTESIAN_POINT('',(10.,15.,0.));\n"
                            "#43 = CARTESIAN_POINT('',(20.,5.,0.));\n#44 = CARTESIAN_POINT('',(30.,10.,0.));\n";
  std::string both = stepModel(data + plain);
  both.replace(both.find("(#11,#15),#26"), 13, "(#11,#15,#50),#26");
  std::ofstream(scratch("part-dropped.step"), std::ios::binary) << both;
  const meshing::CadRods result = meshing::rodsFromCad(scratch("part-dropped.step"), {});
  CHECK(result.structure.rods.size() == 1);
  CHECK(result.report.untranslated == 1);
  CHECK_THAT(result.report.firstUntranslated, Catch::StartsWith("entity #15 (") && Catch::Contains("not translated"));
  CHECK_THAT(cadError("all-dropped.step", stepModel(data)),
             Catch::Contains("the model holds no edge curve; OpenCASCADE could not convert entity #15 ("));
  // A model OpenCASCADE converts whole (the seed's wireframe has a warning, not a failure).
  CHECK(meshing::rodsFromCad("tests/fuzz/seeds/cad/wireframe.step", {}).report.untranslated == 0);
}
