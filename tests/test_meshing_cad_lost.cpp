// rods-from-cad: curves OpenCASCADE cannot make an edge of are counted and named, never dropped
// silently; curve ends are joined only within the joint tolerance.
#include "meshing/meshing.hpp"
#include "tests/meshing/cad_test_support.hpp"
#include "tests/meshing/iges_text.hpp"

#include <catch2/catch.hpp>

#include <cstdio>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

using namespace rodfab;
using namespace rodfab::cad_test;

namespace {

// A 20 mm square of polylines #40 to #43 in curve set #15, with `extra` (the entities `data` gives,
// from #100) as the set's fifth curve; without `extra`, the extra curve alone.
std::string squareWith(const std::string& extra, const std::string& data, bool square = true) {
  std::string corners = "#50 = CARTESIAN_POINT('',(0.,0.,0.));\n#51 = CARTESIAN_POINT('',(20.,0.,0.));\n"
                        "#52 = CARTESIAN_POINT('',(20.,20.,0.));\n#53 = CARTESIAN_POINT('',(0.,20.,0.));\n"
                        "#40 = POLYLINE('',(#50,#51));\n#41 = POLYLINE('',(#51,#52));\n"
                        "#42 = POLYLINE('',(#52,#53));\n#43 = POLYLINE('',(#53,#50));\n";
  const std::string members = square ? "(#40,#41,#42,#43," + extra + ")" : "(" + extra + ")";
  return stepModel("#15 = GEOMETRIC_CURVE_SET(''," + members + ");\n" + (square ? corners : "") + data);
}

const std::string kCubicPoints = "#101 = CARTESIAN_POINT('',(0.,0.,5.));\n#102 = CARTESIAN_POINT('',(5.,5.,5.));\n"
                                 "#103 = CARTESIAN_POINT('',(10.,-5.,5.));\n#104 = CARTESIAN_POINT('',(15.,0.,5.));\n";

std::string lineAlong(const std::string& direction, const std::string& from, const std::string& to) {
  return "#101 = DIRECTION('',(" + direction + "));\n#102 = VECTOR('',#101,1.);\n#103 = CARTESIAN_POINT('',(0.,0.,5.));\n"
         "#104 = LINE('',#103,#102);\n#100 = TRIMMED_CURVE('',#104,(PARAMETER_VALUE(" + from + ")),(PARAMETER_VALUE(" + to +
         ")),.T.,.PARAMETER.);\n";
}

// Each curve OpenCASCADE's STEP transfer makes no edge of (it leaves it out of its curve set with a
// warning, not a failure), as entity #100, and the type the messages name it by.
const std::vector<std::pair<std::string, std::string>> kBadStepCurves = {
    {"#101 = AXIS2_PLACEMENT_3D('',#12,#13,#14);\n#102 = CIRCLE('',#101,-5.);\n"
     "#100 = TRIMMED_CURVE('',#102,(PARAMETER_VALUE(0.)),(PARAMETER_VALUE(6.)),.T.,.PARAMETER.);\n",
     "TRIMMED_CURVE"},  // a circle of negative radius
    {kCubicPoints + "#100 = ( BOUNDED_CURVE() B_SPLINE_CURVE(3,(#101,#102,#103,#104),.UNSPECIFIED.,.F.,.F.) "
                    "B_SPLINE_CURVE_WITH_KNOTS((4,4),(0.,1.),.UNSPECIFIED.) CURVE() GEOMETRIC_REPRESENTATION_ITEM() "
                    "RATIONAL_B_SPLINE_CURVE((1.,0.,1.,1.)) REPRESENTATION_ITEM('') );\n",
     "RATIONAL_B_SPLINE_CURVE"},  // a weight of 0
    {lineAlong("0.,0.,0.", "0.", "10."), "TRIMMED_CURVE"},  // a line without a direction
    {lineAlong("0.,0.,1.", "10", "0"), "TRIMMED_CURVE"},  // trimmed at integers (a STEP real has a point)
    {kCubicPoints + "#100 = B_SPLINE_CURVE_WITH_KNOTS('',3,(#101,#102,#103,#104),.UNSPECIFIED.,.F.,.F.,(4,4),(1.,0.),.UNSPECIFIED.);\n",
     "B_SPLINE_CURVE_WITH_KNOTS"},  // knots decreasing
    {kCubicPoints + "#105 = CARTESIAN_POINT('',(20.,3.,5.));\n#106 = CARTESIAN_POINT('',(25.,0.,5.));\n"
                    "#107 = CARTESIAN_POINT('',(30.,1.,5.));\n#108 = CARTESIAN_POINT('',(35.,0.,5.));\n"
                    "#100 = B_SPLINE_CURVE_WITH_KNOTS('',3,(#101,#102,#103,#104,#105,#106,#107,#108),.UNSPECIFIED.,.F.,.F.,"
                    "(4,4,4),(0.,0.5,1.),.UNSPECIFIED.);\n",
     "B_SPLINE_CURVE_WITH_KNOTS"},  // an inner knot of multiplicity 4, above the degree: the curve falls apart
};

}  // namespace

TEST_CASE("a STEP curve OpenCASCADE makes no edge of is counted and named, beside good ones and alone", "[meshing][cad]") {
  for (std::size_t i = 0; i < kBadStepCurves.size(); ++i) {
    const auto& [data, type] = kBadStepCurves[i];
    INFO("bad curve " << i << ": " << data);
    const fs::path mixed = scratch("square-and-bad-" + std::to_string(i) + ".step");
    std::ofstream(mixed, std::ios::binary) << squareWith("#100", data);
    const meshing::CadRods result = meshing::rodsFromCad(mixed, {});
    CHECK(result.structure.rods.size() == 4);
    CHECK(result.report.untranslated == 1);
    CHECK_THAT(result.report.firstUntranslated, Catch::StartsWith("entity #100 (") && Catch::Contains(type) &&
                                                    Catch::Contains("curve 5 of #15 (GEOMETRIC_CURVE_SET)"));
    CHECK_THAT(cadError("bad-alone-" + std::to_string(i) + ".step", squareWith("#100", data, false)),
               Catch::Contains("the model holds no edge curve; OpenCASCADE could not convert entity #100 (") && Catch::Contains(type));
  }
}

TEST_CASE("a valid STEP curve set loses nothing: no entity counted as untranslated", "[meshing][cad]") {
  const std::string good = kCubicPoints +
                           "#100 = B_SPLINE_CURVE_WITH_KNOTS('',3,(#101,#102,#103,#104),.UNSPECIFIED.,.F.,.F.,(4,4),(0.,1.),.UNSPECIFIED.);\n";
  const fs::path file = scratch("square-and-cubic.step");
  std::ofstream(file, std::ios::binary) << squareWith("#100", good);
  const meshing::CadRods result = meshing::rodsFromCad(file, {});
  CHECK(result.structure.rods.size() == 5);
  CHECK(result.report.untranslated == 0);
  CHECK(result.report.firstUntranslated.empty());
}

namespace {

const std::vector<IgesEntity> kIgesSquare = {{110, "0.,0.,0.,20.,0.,0."}, {110, "20.,0.,0.,20.,20.,0."},
                                             {110, "20.,20.,0.,0.,20.,0."}, {110, "0.,20.,0.,0.,0.,0."}};

meshing::CadRods readIges(const std::string& name, std::vector<IgesEntity> entities) {
  std::ofstream(scratch(name), std::ios::binary) << igesModel(entities);
  return meshing::rodsFromCad(scratch(name), {});
}

// The IGES square with one more entity (D9) after its four lines.
meshing::CadRods readSquareWith(const std::string& name, const IgesEntity& fifth) {
  std::vector<IgesEntity> entities = kIgesSquare;
  entities.push_back(fifth);
  return readIges(name, entities);
}

}  // namespace

TEST_CASE("an IGES composite curve with a member the file does not hold is counted and named", "[meshing][cad]") {
  // D9, a composite of D1 and D3: the square's first two sides, once more.
  const meshing::CadRods whole = readSquareWith("composite.igs", {102, "2,1,3"});
  CHECK(whole.structure.rods.size() == 4);
  CHECK(whole.report.untranslated == 0);
  // Its second member D999 is not in the file: OpenCASCADE's reader drops it with a warning.
  const meshing::CadRods broken = readSquareWith("composite-missing.igs", {102, "2,1,999"});
  CHECK(broken.structure.rods.size() == 4);
  CHECK(broken.report.untranslated == 1);
  CHECK_THAT(broken.report.firstUntranslated, Catch::StartsWith("entity D9 (102 0 CompositeCurve): members left out"));
}

TEST_CASE("an IGES composite warned about for a bad associativity or property pointer loses nothing and is not counted", "[meshing][cad]") {
  // Its members whole; one associativity pointer to nothing, then one property pointer to nothing.
  const meshing::CadRods associativity = readSquareWith("composite-associativity.igs", {102, "2,1,3,1,999,0"});
  CHECK(associativity.structure.rods.size() == 4);
  CHECK(associativity.report.untranslated == 0);
  const meshing::CadRods property = readSquareWith("composite-property.igs", {102, "2,1,3,0,1,999"});
  CHECK(property.structure.rods.size() == 4);
  CHECK(property.report.untranslated == 0);
}

TEST_CASE("an IGES B-spline of weight 0 beside a square is counted and named, as before", "[meshing][cad]") {
  const meshing::CadRods result =
      readSquareWith("weight0.igs", {126, "3,3,0,0,0,0,0.,0.,0.,0.,1.,1.,1.,1.,1.,0.,1.,1.,0.,0.,0.,5.,5.,0.,10.,-5.,0.,15.,0.,0.,0.,1.,0.,0.,1."});
  CHECK(result.structure.rods.size() == 4);
  CHECK(result.report.untranslated == 1);
  CHECK_THAT(result.report.firstUntranslated, Catch::StartsWith("entity D9 (126 0 BSplineCurve): "));
}
