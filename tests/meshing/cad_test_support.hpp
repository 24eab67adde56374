// Shared by the rods-from-cad tests (test_meshing_cad.cpp, test_meshing_cad_hostile.cpp): a scratch
// folder, the MeshError a read gives, distances to exact curves, and STEP models written as text.
#pragma once

#include "meshing/meshing.hpp"
#include "tests/meshing/cad_fixtures.hpp"
#include "tests/meshing/step_text.hpp"
#include "tests/temp_dir.hpp"

#include <Geom_Curve.hxx>
#include <gp_Pnt.hxx>

#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

namespace rodfab::cad_test {

namespace fs = std::filesystem;
using geometry::Vec3;

inline fs::path scratch(const std::string& name) { return rodfab::test::processScratch("cad", name); }

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

inline Vec3 toVec(const gp_Pnt& p) { return {p.X(), p.Y(), p.Z()}; }

// Largest distance from the rod's centerline (sampled) to the exact curve over [first, last], found
// by sampling the exact curve densely and refining with the rod's own closest-point search the other way.
inline double largestDeviation(const geometry::Rod& rod, const Handle(Geom_Curve)& exact, double first, double last) {
  double largest = 0;
  for (int i = 0; i <= 400; ++i) {
    const Vec3 p = toVec(exact->Value(first + (last - first) * i / 400));
    largest = std::max(largest, rod.closestPoint(p).distance);
  }
  return largest;
}

// The curve set #15 holding a cubic B-spline #17 (trimmed by #16) through control points #18 to #23;
// `points` replaces the list of the spline's control points, `degree` its degree.
inline std::string splineData(const std::string& points = "(#18,#19,#20,#21,#22,#23)", const std::string& degree = "3",
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
inline std::string circleData(const std::string& radius) {
  return "#15 = GEOMETRIC_CURVE_SET('',(#16));\n"
         "#16 = TRIMMED_CURVE('',#17,(PARAMETER_VALUE(0.)),(PARAMETER_VALUE(6.28318530718)),.T.,.PARAMETER.);\n"
         "#17 = CIRCLE('',#18," + radius + ");\n#18 = AXIS2_PLACEMENT_3D('',#19,#13,#14);\n"
         "#19 = CARTESIAN_POINT('',(3.,-2.,7.));\n";
}

// The message of the MeshError that reading `text` as `name` gives (checked to start with the file).
inline std::string cadError(const std::string& name, const std::string& text, const meshing::CadRodOptions& options = {}) {
  const fs::path file = scratch(name);
  std::ofstream(file, std::ios::binary) << text;
  return meshErrorOf(file, [&] { meshing::rodsFromCad(file, options); });
}


}  // namespace rodfab::cad_test
