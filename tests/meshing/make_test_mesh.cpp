// Writes a test mesh: make_test_mesh ellipsoid|bumpy FREQUENCY FILE [A B C]
// ellipsoid: semi-axes A B C (mm, default 30 20 15); bumpy: a bumpy sphere of radius A (default 40).
// 20 * FREQUENCY^2 triangles, coordinates rounded to float; FILE ending in .obj is written as OBJ, .ascii.stl as ASCII STL, else binary STL.
#include "tests/meshing/mesh_fixtures.hpp"

#include <cstdio>
#include <cstdlib>
#include <string>

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: make_test_mesh ellipsoid|bumpy FREQUENCY FILE [A B C]\n");
    return 2;
  }
  const std::string kind = argv[1], file = argv[3];
  const int frequency = std::atoi(argv[2]);
  if (frequency < 1 || frequency > 2000 || (kind != "ellipsoid" && kind != "bumpy")) {
    std::fprintf(stderr, "make_test_mesh: bad kind or frequency\n");
    return 2;
  }
  const double a = argc > 4 ? std::atof(argv[4]) : kind == "bumpy" ? 40 : 30;
  const double b = argc > 5 ? std::atof(argv[5]) : 20, c = argc > 6 ? std::atof(argv[6]) : 15;
  rodfab::testing::SimpleMesh mesh =
      kind == "bumpy" ? rodfab::testing::bumpySphere(frequency, a) : rodfab::testing::ellipsoid(frequency, a, b, c);
  rodfab::testing::roundToFloat(mesh);  // every format then holds the same numbers
  const auto endsWith = [&](const std::string& s) { return file.size() >= s.size() && file.compare(file.size() - s.size(), s.size(), s) == 0; };
  if (endsWith(".obj")) rodfab::testing::writeObj(mesh, file);
  else if (endsWith(".ascii.stl")) rodfab::testing::writeAsciiStl(mesh, file);
  else rodfab::testing::writeBinaryStl(mesh, file);
  std::printf("%zu vertices, %zu triangles -> %s\n", mesh.points.size(), mesh.triangles.size(), file.c_str());
  return 0;
}
