// Writes a CAD test model with OpenCASCADE: make_test_cad box|spline|circle FILE.step|FILE.iges
#include "tests/meshing/cad_fixtures.hpp"

#include <cstdio>
#include <string>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: make_test_cad box|spline|circle FILE.step|FILE.iges\n");
    return 2;
  }
  const std::string kind = argv[1], file = argv[2];
  TopoDS_Shape shape;
  if (kind == "box") shape = rodfab::testing::box(10, 20, 30);
  else if (kind == "spline") shape = rodfab::testing::edgeOf(rodfab::testing::testSpline());
  else if (kind == "circle") shape = rodfab::testing::edgeOf(rodfab::testing::testCircle());
  else return 2;
  if (file.size() > 5 && file.substr(file.size() - 5) == ".iges") rodfab::testing::writeIges(shape, file);
  else rodfab::testing::writeStep(shape, file);
  return 0;
}
