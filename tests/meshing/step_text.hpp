// STEP models written as text, for the rods-from-cad tests (tests/meshing/cad_test_support.hpp) and
// bench_meshing: no test framework, no OpenCASCADE.
#pragma once

#include <string>

namespace rodfab::cad_test {

// A STEP model written as OpenCASCADE writes a wireframe: the product and context entities, a curve
// set #15 of the curve #16, the entities `data` gives (#15 onwards) and the length unit #27.
inline std::string stepModel(const std::string& data, const std::string& unit = "( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) )") {
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

}  // namespace rodfab::cad_test
