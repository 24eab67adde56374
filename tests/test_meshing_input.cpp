// meshing/: the mesh reader's checks (bad meshes, PLY headers and lists, OBJ face corners, bytes in
// memory) and the crowded-vertex check made before simplifying, each error naming the file and what is
// wrong. Meshes written here as text or bytes, not by CGAL.
#include "meshing/mesh.hpp"  // internal: parseMesh, checkCrowdedVertices
#include "meshing/meshing.hpp"
#include "tests/meshing/mesh_fixtures.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace rodfab;
using testing::scratch;
using testing::writeText;

namespace {

// rodsFromMesh's error for `file` (`faces` asked for), checked to name the file first; "no error" if it read.
std::string meshError(const fs::path& file, std::size_t faces = 4) {
  meshing::MeshRodOptions options;
  options.faces = faces;
  try {
    meshing::rodsFromMesh(file, options);
  } catch (const meshing::MeshError& e) {
    CHECK(std::string(e.what()).rfind(file.string() + ": ", 0) == 0);
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST_CASE("bad meshes get an error naming the file and the problem", "[meshing]") {
  CHECK_THAT(meshError(scratch("missing.stl")), Catch::Contains("no such file"));
  writeText(scratch("empty.obj"), "");
  CHECK_THAT(meshError(scratch("empty.obj")), Catch::Contains("no faces"));
  writeText(scratch("points.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\n");  // complete, but no surface
  CHECK_THAT(meshError(scratch("points.obj")), Catch::Contains("points.obj: the file holds 3 vertices and no faces (is it complete?)"));
  writeText(scratch("negative.ply"), "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                                     "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 -5\n");
  CHECK_THAT(meshError(scratch("negative.ply")), Catch::Contains("face 0 refers to vertex -5 of 4 (vertices count from 0)"));
  writeText(scratch("garbage.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n");
  CHECK_THAT(meshError(scratch("garbage.off")), Catch::Contains("not a readable off mesh"));
  writeText(scratch("huge.off"), "OFF\n1000000000 1000000000 0\n");
  CHECK_THAT(meshError(scratch("huge.off")), Catch::Contains("OFF header declares"));
  // Lines CGAL's OFF reader would misread (unchecked casts, a colour read past the line): refused first.
  writeText(scratch("index.off"), "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 3e31\n");
  CHECK_THAT(meshError(scratch("index.off")), Catch::Contains("OFF line 7: a face refers to a vertex"));
  // nOFF's dimension before the counts, which the check read as counts (found by fuzzing).
  writeText(scratch("dims.off"), "nOFF\n3 4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n");
  CHECK_THAT(meshError(scratch("dims.off")), Catch::Contains("OFF line 1: 'nOFF' (OFF of n dimensions) is not read"));
  // A skeleton, which CGAL's OFF reader takes too, its polylines unchecked (500 M points: 18 s, 3.9 GB).
  writeText(scratch("skel.off"), "SKEL\n1 1\n0 0 0\n500000000 0\n");
  CHECK_THAT(meshError(scratch("skel.off")), Catch::Contains("OFF line 1: 'SKEL' is not an OFF keyword"));
  writeText(scratch("edges.off"), "OFF\n4 1 3.30\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n");
  CHECK_THAT(meshError(scratch("edges.off")), Catch::Contains("OFF line 2: expected the vertex, face and edge counts on one line"));
  writeText(scratch("short.off"), "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n4 0 1\n");
  CHECK_THAT(meshError(scratch("short.off")), Catch::Contains("a face of 4 corners needs as many"));
  writeText(scratch("mesh.dxf"), "x");
  CHECK_THAT(meshError(scratch("mesh.dxf")), Catch::Contains("unknown mesh format"));
  // Three triangles on one edge.
  writeText(scratch("fin.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n");
  CHECK_THAT(meshError(scratch("fin.obj")), Catch::Contains("non-manifold mesh") && Catch::Contains("(0, 0, 0) to (1, 0, 0)"));
  // Two tetrahedra sharing one vertex only.
  writeText(scratch("bowtie.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv -1 0 0\nv 0 -1 0\nv 0 0 -1\n"
                                   "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\nf 1 5 6\nf 1 6 7\nf 1 7 5\nf 5 7 6\n");
  CHECK_THAT(meshError(scratch("bowtie.obj")), Catch::Contains("non-manifold") && Catch::Contains("(0, 0, 0)"));
  writeText(scratch("sliver.obj"), "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n");
  CHECK_THAT(meshError(scratch("sliver.obj")), Catch::Contains("degenerate mesh: triangle") && Catch::Contains("zero area"));
  writeText(scratch("repeat.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2\n");
  CHECK_THAT(meshError(scratch("repeat.obj")), Catch::Contains("two corners at the same point (1, 0, 0)"));
  // A binary STL (which can hold any float) with a NaN coordinate.
  testing::SimpleMesh nan = testing::ellipsoid(1, 10, 10, 10);
  nan.points[3].y() = std::nan("");
  testing::writeBinaryStl(nan, scratch("nan.stl"));
  CHECK_THAT(meshError(scratch("nan.stl")), Catch::Contains("not a finite number"));
  // Numbers the readers' streams cannot hold stop them; the message names the line and the token.
  writeText(scratch("overflow.stl"), "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1e999 0 0\n"
                                     "vertex 0 1 0\nendloop\nendfacet\nendsolid x\n");
  CHECK_THAT(meshError(scratch("overflow.stl")), Catch::Contains("line 5: '1e999' is not a finite number"));
  writeText(scratch("inf.obj"), "v 0 0 0\nv 1 0 0\nv 0 -inf 0\nf 1 2 3\n");
  CHECK_THAT(meshError(scratch("inf.obj")), Catch::Contains("line 3: '-inf'"));
  writeText(scratch("overflow.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1e400 0\n3 0 1 2\n");
  CHECK_THAT(meshError(scratch("overflow.off")), Catch::Contains("line 5: '1e400'"));
  testing::writeObj(testing::ellipsoid(1, 10, 10, 10), scratch("small.obj"));
  CHECK_THAT(meshError(scratch("small.obj"), 100), Catch::Contains("20 triangles, fewer than the 100 asked for"));
}

TEST_CASE("PLY headers CGAL would misread are refused first, naming the line", "[meshing]") {
  writeText(scratch("prop.ply"), "ply\nformat ascii 1.0\nproperty float x\nelement vertex 1\nend_header\n0\n");
  CHECK_THAT(meshError(scratch("prop.ply")), Catch::Contains("PLY header line 3: a property before any element"));
  // A vertex coordinate declared as a list: CGAL's reader called through a null pointer (found by fuzzing).
  writeText(scratch("listy.ply"), "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty list uchar float y\n"
                                  "property float z\nend_header\n0 1 0 0\n");
  CHECK_THAT(meshError(scratch("listy.ply")), Catch::Contains("PLY header line 5: vertex coordinate y is a list (expected a float or double)"));
  // The same for an element "vertices", which CGAL reads points from too (found by fuzzing).
  writeText(scratch("vertices.ply"), "ply\nformat ascii 1.0\nelement vertices 1\nproperty uchar x\nend_header\n0\n");
  CHECK_THAT(meshError(scratch("vertices.ply")), Catch::Contains("PLY header line 4: vertex coordinate x of type 'uchar' (expected float or double)"));
  // A second format line (CGAL reads line 2's only) and no end_header (CGAL then reads the body past the
  // end of the file: list lengths of gigabytes, found by fuzzing).
  writeText(scratch("formats.ply"), "ply\nformat binary_little_endian 1.0\nformat ascii 1.0\nelement vertex 1\nend_header\n");
  CHECK_THAT(meshError(scratch("formats.ply")), Catch::Contains("PLY header line 3: a format line where PLY has it on line 2 only"));
  // Line 2 not a format line: CGAL reads its second word as the format anyway.
  writeText(scratch("starformat.ply"), "ply\n*format binary_little_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n");
  CHECK_THAT(meshError(scratch("starformat.ply")), Catch::Contains("PLY header line 2: expected 'format ascii 1.0'"));
  // A property of a type CGAL does not know, which it skips while the list check would read nothing.
  writeText(scratch("floz.ply"), "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty floz at\nend_header\n0 0\n");
  CHECK_THAT(meshError(scratch("floz.ply")), Catch::Contains("PLY header line 5: a property of unknown type 'floz'"));
  // A hostile file's names reach the message escaped, never as terminal control sequences.
  writeText(scratch("escape.ply"), "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty \x1b[2J at\nend_header\n0 0\n");
  CHECK_THAT(meshError(scratch("escape.ply")), Catch::Contains("PLY header line 5: a property of unknown type '\\x1b[2J'"));
  writeText(scratch("escape2.ply"), "ply\nformat ascii 1.0\nelement f\x1b]0;x\x07 1\nproperty int n\nend_header\n1.5\n");
  CHECK_THAT(meshError(scratch("escape2.ply")), Catch::Contains("PLY f\\x1b]0;x\\x07 0: '1.5' is not an integer"));
  // An element count read as CGAL reads it, a std::size_t from the stream: "100000000000ex" is 10^11
  // elements to CGAL (a double's read failed, so the check saw 0: a 10 s loop found by fuzzing).
  writeText(scratch("count.ply"), "ply\nformat ascii 1.0\nelement vertex 100000000000ex\nproperty float x\nend_header\n0\n");
  CHECK_THAT(meshError(scratch("count.ply")), Catch::Contains("PLY header line 3: an element count the file's"));
  writeText(scratch("endless.ply"), "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nend_@header\n");
  CHECK_THAT(meshError(scratch("endless.ply")), Catch::Contains("the PLY header has no end_header line"));
  // Lines CGAL's reader refuses with no word on why are named: each is read as CGAL reads it (a word
  // from the line's stream), so "element vertex x" is a missing count, not 0 elements.
  writeText(scratch("signature.ply"), "PLY\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n");
  CHECK_THAT(meshError(scratch("signature.ply")), Catch::Contains("PLY header line 1: expected 'ply'"));
  writeText(scratch("version.ply"), "ply\nformat ascii\nelement vertex 1\nproperty float x\nend_header\n0\n");
  CHECK_THAT(meshError(scratch("version.ply")), Catch::Contains("PLY header line 2: expected 'format ascii 1.0'"));
  writeText(scratch("nocount.ply"), "ply\nformat ascii 1.0\nelement vertex x\nproperty float x\nend_header\n0\n");
  CHECK_THAT(meshError(scratch("nocount.ply")), Catch::Contains("PLY header line 3: expected 'element NAME COUNT'"));
  writeText(scratch("floatcount.ply"), "ply\nformat ascii 1.0\nelement face 1\nproperty list double int vertex_indices\nend_header\n3 0 1 2\n");
  CHECK_THAT(meshError(scratch("floatcount.ply")), Catch::Contains("PLY header line 4: a list counted by a double (expected an integer count type"));
  writeText(scratch("noname.ply"), "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int\nend_header\n0\n");
  CHECK_THAT(meshError(scratch("noname.ply")), Catch::Contains("PLY header line 4: a property without a name"));
  // A header read once for both checks: the body after a CRLF header is read from the same byte CGAL
  // reads it from (the list of 3 corners fits, the next face's count is past the end).
  writeText(scratch("crlf.ply"), "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty float x\r\nproperty float y\r\n"
                                 "property float z\r\nelement face 2\r\nproperty list uchar int vertex_indices\r\nend_header\r\n"
                                 "0 0 0\r\n1 0 0\r\n0 1 0\r\n3 0 1 2\r\n");
  CHECK_THAT(meshError(scratch("crlf.ply")), Catch::Contains("PLY face 1: the file ends inside it"));
}

TEST_CASE("the mesh reader on bytes in memory", "[meshing]") {
  std::ostringstream obj;
  const testing::SimpleMesh mesh = testing::ellipsoid(2, 3, 3, 3);
  for (const auto& p : mesh.points) obj << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  for (const auto& t : mesh.triangles) obj << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
  const meshing::MeshCounts counts = meshing::checkMeshBytes(obj.str(), "obj", "memory");
  CHECK(counts.faces == 80);
  CHECK(counts.vertices == 42);
  CHECK_THROWS_AS(meshing::checkMeshBytes("solid x\nendsolid", "stl", "memory"), meshing::MeshError);
}

// A vertex of n triangles costs CGAL's simplifier n^3 (meshing/README.md, "Crowded vertices"): a double
// cone of two apexes of 1,000 took 10.7 s, of 3,000 over a minute; a polygon of 2,000 corners 43 s.
TEST_CASE("vertices of too many triangles are refused before simplification, the most crowded named", "[meshing][hostile]") {
  const double pi = std::acos(-1.0);
  // A closed double cone: apexes (0, 0, 0) and (0, 0, 10), each a corner of n triangles.
  const auto doubleCone = [&](int n) {
    std::ostringstream obj;
    obj.precision(17);
    obj << "v 0 0 10\nv 0 0 0\n";
    for (int i = 0; i < n; ++i) obj << "v " << 10 * std::cos(2 * pi * i / n) << ' ' << 10 * std::sin(2 * pi * i / n) << " 5\n";
    for (int i = 0; i < n; ++i) obj << "f 1 " << 3 + i << ' ' << 3 + (i + 1) % n << "\nf 2 " << 3 + (i + 1) % n << ' ' << 3 + i << '\n';
    return obj.str();
  };
  // One flat polygon of n corners: fanned from its first corner, (10, 0, 0), a corner of n - 2 triangles.
  const auto polygon = [&](int n) {
    std::ostringstream obj;
    obj.precision(17);
    for (int i = 0; i < n; ++i) obj << "v " << 10 * std::cos(2 * pi * i / n) << ' ' << 10 * std::sin(2 * pi * i / n) << " 0\n";
    obj << 'f';
    for (int i = 1; i <= n; ++i) obj << ' ' << i;
    obj << '\n';
    return obj.str();
  };
  // The mesh as read, then the check rodsFromMesh makes before simplifying it.
  const auto read = [](const std::string& obj) {
    meshing::ReadStats stats;
    return meshing::parseMesh(obj, "obj", "m.obj", stats);
  };
  const auto error = [&](const std::string& obj) {
    try {
      meshing::checkCrowdedVertices(read(obj), "m.obj");
    } catch (const meshing::MeshError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  // One vertex of up to 1,024 passes; 1,025 does not.
  CHECK(error(polygon(1026)) == "no error");
  CHECK(read(polygon(1026)).triangles.size() == 1024);
  CHECK_THAT(error(polygon(1027)), Catch::Contains("m.obj: the vertex (10, 0, 0) is a corner of 1025 triangles:") &&
                                       Catch::Contains("up to 1024 triangles") && Catch::Contains("triangulate it first"));
  // Several: the sum of their counts cubed up to 1024^3 (2 x 812^3 passes, 2 x 813^3 does not).
  CHECK(error(doubleCone(812)) == "no error");
  CHECK_THAT(error(doubleCone(813)), Catch::Contains("the vertex (0, 0, 0) is a corner of 813 triangles (and 1 more vertex of more than 32)"));
  CHECK_THAT(error(doubleCone(1000)), Catch::Contains("the vertex (0, 0, 0) is a corner of 1000 triangles"));
  // Up to 32 a vertex does not count.
  CHECK(error(doubleCone(32)) == "no error");
  // A crowded mesh is a valid mesh: read and checked (rodsFromMesh makes rods of it as it is, with --faces
  // its own count); asked to be simplified, it is refused before the simplification starts.
  CHECK(meshing::checkMeshBytes(doubleCone(1000), "obj", "m.obj").faces == 2000);
  const fs::path cone = scratch("crowded-cone.obj");
  writeText(cone, doubleCone(1000));
  meshing::MeshRodOptions fewer;
  fewer.faces = 500;
  CHECK_THROWS_WITH(meshing::rodsFromMesh(cone, fewer), Catch::Contains("cone.obj: the vertex (0, 0, 0) is a corner of 1000 triangles"));
}

TEST_CASE("OBJ face corners are checked where CGAL would misread them", "[meshing]") {
  std::ostringstream body;
  const testing::SimpleMesh mesh = testing::ellipsoid(1, 3, 3, 3);
  for (const auto& p : mesh.points) body << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  const std::string vertices = body.str();  // 12 vertices; the faces below are added line by line
  std::string faces;
  for (const auto& t : mesh.triangles) faces += "f " + std::to_string(t[0] + 1) + ' ' + std::to_string(t[1] + 1) + ' ' + std::to_string(t[2] + 1) + '\n';
  const auto error = [&](const std::string& lastFace) {
    try {
      meshing::checkMeshBytes(vertices + faces + lastFace, "obj", "m.obj");
    } catch (const meshing::MeshError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string line = "OBJ line " + std::to_string(12 + 20 + 1) + ": ";
  // Past 2^31 CGAL's int read fails and the face loses a corner; past the vertices the file fails as a whole.
  CHECK_THAT(error("f 1 2 3000000000\n"), Catch::Contains(line + "face corner '3000000000' names no vertex: expected 1 .. 12"));
  CHECK_THAT(error("f 1 2 13\n"), Catch::Contains(line + "face corner '13' names no vertex"));
  CHECK_THAT(error("f 1 2 0\n"), Catch::Contains(line + "face corner '0' names no vertex"));
  CHECK_THAT(error("f 1 2 -13\n"), Catch::Contains("(or -1 .. -12, counted back from this line)"));
  CHECK_THAT(error("f 1 2 x 3\n"), Catch::Contains(line + "face corner 'x' is not a vertex number"));
  CHECK_THAT(error("f 1 2\n"), Catch::Contains(line + "a face with 2 corners (expected 3 or more)"));
  // What CGAL reads right passes: relative corners, texture and normal numbers, CRLF line ends, a
  // comment; tab-separated corners (which CGAL's reader would cut short) are read as spaces. Each
  // repeats the first face with the other orientation, so the check gets past the reader (to the
  // mesh checks, which refuse the repeated face) without a reader error.
  const auto& t = mesh.triangles[0];
  const std::string a = std::to_string(t[0] + 1), b = std::to_string(t[1] + 1), c = std::to_string(t[2] + 1);
  for (const std::string& face : {"f " + a + "/1/1 " + c + "/2/2 " + b + "//3\r\n", "f " + a + "\t" + c + "\t" + b + " # c\n",
                                  "f " + std::to_string(int(t[0]) - 12) + ' ' + std::to_string(int(t[2]) - 12) + ' ' + std::to_string(int(t[1]) - 12) + '\n'}) {
    const std::string message = error(face);
    CHECK_THAT(message, !Catch::Contains("OBJ line") && !Catch::Contains("not a readable"));
    CHECK_THAT(message, Catch::Contains("non-manifold"));
  }
}

namespace {

// A tetrahedron as PLY: `format` ascii, binary_little_endian or binary_big_endian; the faces' corner
// lists of `countType`, the first face's count replaced by `firstCount`, and a texture-coordinate list
// (ushort count, two floats) after each face's corners, so a list follows a list.
std::string tetrahedronPly(const std::string& format, const std::string& countType, std::uint32_t firstCount) {
  const double points[4][3] = {{0, 0, 0}, {10, 0, 0}, {0, 10, 0}, {0, 0, 10}};
  const int faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  std::string out = "ply\nformat " + format + " 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\n" +
                    "element face 4\nproperty list " + countType + " int vertex_indices\nproperty list ushort float texcoord\nend_header\n";
  const bool big = format == "binary_big_endian";
  const auto put = [&](const auto value) {
    char raw[sizeof value];
    std::memcpy(raw, &value, sizeof value);
    if (big) std::reverse(raw, raw + sizeof value);
    out.append(raw, sizeof value);
  };
  const auto count = [&](std::uint32_t n) {
    if (countType == "uchar") put(static_cast<std::uint8_t>(n));
    else put(n);
  };
  for (const auto& p : points)
    if (format == "ascii") out += std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) + "\n";
    else put(p[0]), put(p[1]), put(p[2]);
  for (int f = 0; f < 4; ++f) {
    const std::uint32_t n = f == 0 ? firstCount : 3;
    if (format == "ascii") {
      out += std::to_string(n) + " " + std::to_string(faces[f][0]) + " " + std::to_string(faces[f][1]) + " " +
             std::to_string(faces[f][2]) + " 2 0.5 0.5\n";
      continue;
    }
    count(n), put(faces[f][0]), put(faces[f][1]), put(faces[f][2]);
    put(std::uint16_t{2}), put(0.5f), put(0.5f);
  }
  return out;
}

}  // namespace

TEST_CASE("a PLY list longer than the file is refused before CGAL sizes it", "[meshing][hostile]") {
  // CGAL's reader allocated a lying list's length first: 2,000,000,000 corners in a file of a few
  // hundred bytes grew rods-from-mesh to the memory budget (7.9 GB) before it failed.
  for (const std::string format : {"ascii", "binary_little_endian", "binary_big_endian"})
    for (const std::string countType : {"uchar", "uint"}) {
      INFO(format << ", " << countType);
      const meshing::MeshCounts counts = meshing::checkMeshBytes(tetrahedronPly(format, countType, 3), "ply", "t.ply");
      CHECK(counts.vertices == 4);
      CHECK(counts.faces == 4);
      const std::uint32_t lie = countType == "uchar" ? 250 : 2'000'000'000;
      CHECK_THROWS_WITH(meshing::checkMeshBytes(tetrahedronPly(format, countType, lie), "ply", "t.ply"),
                        Catch::StartsWith("t.ply: PLY face 0: a list of " + std::to_string(lie) + " entries, more than the "));
    }
  // The second list of a face (texture coordinates) is checked too.
  std::string texture = tetrahedronPly("ascii", "uchar", 3);
  texture.replace(texture.rfind(" 2 0.5 0.5"), 10, " 99 0.5 0.5");
  CHECK_THROWS_WITH(meshing::checkMeshBytes(texture, "ply", "t.ply"), Catch::Contains("PLY face 3: a list of 99 entries"));
  // A negative or fractional length is no length.
  for (const auto& [length, message] : {std::pair<std::string, std::string>{"-3", "a list of -3 entries"},
                                        {"2.5", "'2.5' is not an integer (a uchar property)"}}) {
    std::string lying = tetrahedronPly("ascii", "uchar", 3);
    lying.replace(lying.find("\n3 0 2 1 ") + 1, 1, length);
    CHECK_THROWS_WITH(meshing::checkMeshBytes(lying, "ply", "t.ply"), Catch::Contains("PLY face 0: " + message));
  }
  // A word CGAL's stream would read as two numbers ("0-1": 0, then -1, as a list length 4294967295 in
  // CGAL: a 4 GB allocation, found by fuzzing), or no number at all, in any property.
  std::string twoInOne = tetrahedronPly("ascii", "uint", 3);
  twoInOne.replace(twoInOne.find("\n3 0 2 1 ") + 3, 1, "0-1");
  CHECK_THROWS_WITH(meshing::checkMeshBytes(twoInOne, "ply", "t.ply"), Catch::Contains("PLY face 0: '0-1' is not an integer (a int property)"));
  std::string word = tetrahedronPly("ascii", "uchar", 3);
  word.replace(word.find(" 0.5 0.5\n"), 4, " 0.5x");
  CHECK_THROWS_WITH(meshing::checkMeshBytes(word, "ply", "t.ply"), Catch::Contains("PLY face 0: '0.5x' is not a number (a float property)"));
  // A body cut short (CGAL reads past its end into uninitialised numbers: list lengths of gigabytes,
  // found by fuzzing): refused at the item where it ends, ASCII or binary in either byte order.
  for (const std::string format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    const std::string whole = tetrahedronPly(format, "uint", 3);
    CHECK_THROWS_WITH(meshing::checkMeshBytes(whole.substr(0, whole.size() - 10), "ply", "t.ply"),
                      Catch::StartsWith("t.ply: PLY face 3: the file ends inside it") && Catch::Contains("was it cut short?"));
  }
}

namespace {

// The ellipsoid's 80 triangles as OBJ text, and as binary STL with `declared` in its count field.
std::string ellipsoidObj() {
  std::ostringstream obj;
  const testing::SimpleMesh mesh = testing::ellipsoid(2, 3, 3, 3);
  for (const auto& p : mesh.points) obj << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  for (const auto& t : mesh.triangles) obj << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
  return obj.str();
}
std::string ellipsoidStl(std::uint32_t declared) {
  const testing::SimpleMesh mesh = testing::ellipsoid(2, 3, 3, 3);
  std::string out(80, ' ');
  out.append(reinterpret_cast<const char*>(&declared), 4);
  for (const auto& t : mesh.triangles) {
    float values[12] = {};
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) values[3 + 3 * c + k] = static_cast<float>(mesh.points[static_cast<std::size_t>(t[static_cast<std::size_t>(c)])][k]);
    out.append(reinterpret_cast<const char*>(values), sizeof values);
    out.append(2, '\0');
  }
  return out;
}

}  // namespace

// CGAL's readers stop at the counts a header declares: faces past a stale count were dropped without a
// word (a sphere of 1,280 triangles whose count said 640 made rods over half of it, exit 0).
TEST_CASE("faces past the count a mesh file declares are refused, not dropped", "[meshing][hostile]") {
  CHECK(meshing::checkMeshBytes(ellipsoidStl(80), "stl", "e.stl").faces == 80);
  CHECK(meshing::checkMeshBytes(ellipsoidStl(80) + std::string(7, '\0'), "stl", "e.stl").faces == 80);  // padding
  CHECK_THROWS_WITH(meshing::checkMeshBytes(ellipsoidStl(40), "stl", "e.stl"),
                    "e.stl: binary STL: its header declares 40 triangles (2084 bytes), but the file holds 4084 bytes: the count is "
                    "smaller than the data (nothing was read)");
  CHECK_THROWS_WITH(meshing::checkMeshBytes(ellipsoidStl(81), "stl", "e.stl"), Catch::Contains("was it cut short?"));
  std::string solidHeader = ellipsoidStl(40);  // a binary header may start with "solid" too
  solidHeader.replace(0, 5, "solid");
  CHECK_THROWS_WITH(meshing::checkMeshBytes(solidHeader, "stl", "e.stl"), Catch::Contains("the count is smaller than the data"));

  const std::string tetrahedronOff = "OFF\n4 4 0\n0 0 0\n10 0 0\n0 10 0\n0 0 10\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  CHECK(meshing::checkMeshBytes(tetrahedronOff + "# a comment\n\n\x1a", "off", "t.off").faces == 4);  // and a DOS end-of-file mark
  std::string stale = tetrahedronOff;
  stale.replace(stale.find("4 4 0"), 5, "4 3 0");
  CHECK_THROWS_WITH(meshing::checkMeshBytes(stale, "off", "t.off"),
                    "t.off: OFF line 10: more lines follow the 3 faces the header declares: its face count is smaller than the file's "
                    "(nothing was read)");

  for (const std::string format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    INFO(format);
    std::string ply = tetrahedronPly(format, "uchar", 3);
    ply.replace(ply.find("element face 4"), 14, "element face 3");
    CHECK_THROWS_WITH(meshing::checkMeshBytes(ply, "ply", "t.ply"), Catch::Contains("t.ply: PLY: ") &&
                                                                       Catch::Contains("bytes follow the elements the header declares (face last)"));
  }
}

TEST_CASE("OBJ line elements and a UTF-8 byte order mark are read past, not failed on", "[meshing]") {
  const std::string obj = ellipsoidObj();
  // Polylines ("l") are no surface: CGAL's reader failed the whole file ("not a readable obj mesh").
  const meshing::MeshCounts withLines = meshing::checkMeshBytes("l 1 2 3\n" + obj + "l 4 5\nl\t6 7\n", "obj", "l.obj");
  CHECK(withLines.faces == 80);
  CHECK(withLines.vertices == 42);
  // A byte order mark glued itself to the first "v": vertex 1 was lost and a face 99 lines on blamed.
  CHECK(meshing::checkMeshBytes("\xEF\xBB\xBF" + obj, "obj", "bom.obj").vertices == 42);
  CHECK(meshing::checkMeshBytes("\xEF\xBB\xBF" "OFF\n4 4 0\n0 0 0\n10 0 0\n0 10 0\n0 0 10\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n", "off", "bom.off")
            .faces == 4);
  // Indented, or right after the mark, as CGAL reads a line's first word.
  CHECK(meshing::checkMeshBytes("\xEF\xBB\xBF" "l 1 2\n" + obj + "   l 3 4\nl\n", "obj", "l.obj").faces == 80);
  // A text STL's mark: its "solid" was read as a binary triangle count.
  const fs::path text = scratch("bom-text.stl");
  testing::writeAsciiStl(testing::ellipsoid(2, 3, 3, 3), text.string());
  std::ifstream in(text, std::ios::binary);
  const std::string stl((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  CHECK(meshing::checkMeshBytes("\xEF\xBB\xBF" + stl, "stl", "bom.stl").faces == 80);
  // A binary PLY ending in a line break or two, as some writers leave it.
  CHECK(meshing::checkMeshBytes(tetrahedronPly("binary_little_endian", "uchar", 3) + "\r\n", "ply", "t.ply").faces == 4);
  CHECK_THROWS_WITH(meshing::checkMeshBytes(tetrahedronPly("binary_little_endian", "uchar", 3) + std::string(17, '\n'), "ply", "t.ply"),
                    Catch::Contains("17 bytes follow the elements the header declares"));
}
