// Mesh files through CGAL's readers, then the checks rodfab relies on: finite coordinates, triangles
// (polygons fanned), welded vertices, no degenerate face, manifold edges and vertices, one orientation;
// and the check rodsFromMesh makes before simplifying, of vertices of so many triangles that it stalls.
#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "geometry/rod.hpp"
#include "meshing/input_file.hpp"
#include "meshing/mesh.hpp"
#include "meshing/ply_checks.hpp"
#include "meshing/text_mesh_checks.hpp"

#include <CGAL/IO/OBJ.h>
#include <CGAL/IO/OFF.h>
#include <CGAL/IO/PLY.h>
#include <CGAL/IO/STL.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <numeric>
#include <sstream>
#include <utility>

namespace rodfab::meshing {

namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Polygon = std::vector<std::size_t>;

// Bytes of memory the readers and the soup may need per byte of file (the densest text, "f 1 2 3",
// becomes a 64-byte polygon), and per triangle once read (soup, canonical mesh, CGAL's simplification
// mesh and the AABB tree of the original surface).
constexpr std::uint64_t kParseBytesPerFileByte = 14;
constexpr std::uint64_t kBytesPerTriangle = 1000;

std::string where(const Vec3& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.6g, %.6g, %.6g)", p.x(), p.y(), p.z());
  return buf;
}

// A token that starts like a number: a digit, a point, or a sign, inf or nan spelling.
bool looksNumeric(const std::string& token) {
  const std::size_t at = token[0] == '+' || token[0] == '-' ? 1 : 0;
  if (at >= token.size()) return false;
  const char c = static_cast<char>(std::tolower(static_cast<unsigned char>(token[at])));
  return std::isdigit(static_cast<unsigned char>(c)) || c == '.' || c == 'i' || c == 'n';
}

// The readers stop, without saying where, at a number the stream cannot hold (1e999, inf, nan): the
// message names the line and the token so the user can find it. Text formats only (a binary STL's
// floats are checked by checkBinaryStlNumbers); nothing found leaves the generic message.
// `verticesOnly`: the vertices read when no face was (CGAL's OBJ reader fails a file of vertices
// alone, which is no surface), said instead of the generic message.
std::string unreadableMeshMessage(const std::string& bytes, const std::string& format, std::size_t verticesOnly) {
  const std::string generic =
      verticesOnly > 0 ? "the file holds " + std::to_string(verticesOnly) + " vertices and no faces (is it complete?)"
                       : "not a readable " + format + " mesh (the " + format + " reader stopped; is the file complete?)";
  std::uint32_t count = 0;
  if (bytes.size() >= 84) std::memcpy(&count, bytes.data() + 80, 4);
  if (bytes.size() >= 84 && 84 + 50 * std::uint64_t(count) == bytes.size()) return generic;
  std::istringstream in(bytes);
  std::string line, token;
  for (int number = 1; std::getline(in, line); ++number) {
    std::istringstream words(line.substr(0, line.find('#')));
    while (words >> token) {
      if (!looksNumeric(token)) continue;
      errno = 0;
      char* end = nullptr;
      const double value = std::strtod(token.c_str(), &end);
      if (end == token.c_str()) continue;  // a word such as "normal"
      if (!std::isfinite(value) || (errno == ERANGE && std::abs(value) > 1))
        return "line " + std::to_string(number) + ": '" + token.substr(0, 40) + "' " + detail::kNotFinite;
    }
  }
  return generic;
}

bool readSoup(const std::string& bytes, const std::string& format, std::vector<Point>& points,
              std::vector<Polygon>& polygons, const std::string& source) {
  if (format == "stl") detail::checkBinaryStlNumbers(bytes, source);
  std::istringstream in(bytes, std::ios::in | std::ios::binary);
  const auto quiet = CGAL::parameters::verbose(false);
  if (format == "stl") return CGAL::IO::read_STL(in, points, polygons, quiet);
  if (format == "obj") return CGAL::IO::read_OBJ(in, points, polygons, quiet);
  if (format == "off") return CGAL::IO::read_OFF(in, points, polygons, quiet);
  if (format == "ply") return CGAL::IO::read_PLY(in, points, polygons, quiet);
  return false;
}

// Triangles of the soup (polygons fanned from their first corner), after checking indices and coordinates.
std::vector<Triangle> triangulate(const std::vector<Point>& points, const std::vector<Polygon>& polygons,
                                  const std::string& source) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Point& p = points[i];
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(p[a]) || std::abs(p[a]) > geometry::kMaxCoordinateMm)
        throw MeshError(source, "vertex " + std::to_string(i) + " has a coordinate that is not a finite number within ±1e9 mm");
  }
  if (points.size() >= std::numeric_limits<std::uint32_t>::max())
    throw MeshError(source, "more than 4 billion vertices");
  std::vector<Triangle> triangles;
  for (std::size_t f = 0; f < polygons.size(); ++f) {
    const Polygon& poly = polygons[f];
    if (poly.size() < 3) throw MeshError(source, "face " + std::to_string(f) + " has fewer than 3 corners");
    for (std::size_t v : poly)
      if (v >= points.size())
        // A negative index (PLY's are signed) arrives wrapped around to near 2^64: said as written.
        throw MeshError(source, "face " + std::to_string(f) + " refers to vertex " +
                                    (v > std::size_t(std::numeric_limits<std::int64_t>::max()) ? std::to_string(std::int64_t(v)) : std::to_string(v)) +
                                    " of " + std::to_string(points.size()) + " (vertices count from 0)");
    for (std::size_t k = 1; k + 1 < poly.size(); ++k)
      triangles.push_back({static_cast<std::uint32_t>(poly[0]), static_cast<std::uint32_t>(poly[k]),
                           static_cast<std::uint32_t>(poly[k + 1])});
  }
  return triangles;
}

// Identical points become one vertex; vertices end up sorted lexicographically.
TriangleMesh weld(const std::vector<Point>& points, std::vector<Triangle> triangles, ReadStats& stats) {
  std::vector<std::uint32_t> order(points.size());
  std::iota(order.begin(), order.end(), 0u);
  auto less = [&](std::uint32_t a, std::uint32_t b) {
    const Point &p = points[a], &q = points[b];
    if (p.x() != q.x()) return p.x() < q.x();
    if (p.y() != q.y()) return p.y() < q.y();
    if (p.z() != q.z()) return p.z() < q.z();
    return a < b;
  };
  std::sort(order.begin(), order.end(), less);
  TriangleMesh mesh;
  std::vector<std::uint32_t> newIndex(points.size());
  for (std::uint32_t i : order) {
    const Vec3 p(points[i].x(), points[i].y(), points[i].z());
    if (mesh.points.empty() || mesh.points.back() != p) mesh.points.push_back(p);
    newIndex[i] = static_cast<std::uint32_t>(mesh.points.size() - 1);
  }
  stats.weldedVertices = points.size() - mesh.points.size();
  for (Triangle& t : triangles)
    for (auto& v : t) v = newIndex[v];
  mesh.triangles = std::move(triangles);
  return mesh;
}

void checkDegenerate(const TriangleMesh& mesh, const std::string& source) {
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    const Triangle& t = mesh.triangles[f];
    const Vec3 &a = mesh.points[t[0]], &b = mesh.points[t[1]], &c = mesh.points[t[2]];
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
      throw MeshError(source, "degenerate mesh: triangle " + std::to_string(f) + " has two corners at the same point " +
                                  where(t[0] == t[1] || t[0] == t[2] ? a : b));
    const double longest = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    if ((b - a).cross(c - a).norm() <= 1e-12 * longest)
      throw MeshError(source, "degenerate mesh: triangle " + std::to_string(f) + " has zero area (corners in a line) near " +
                                  where((a + b + c) / 3));
  }
}

// An edge of more than two triangles, or two triangles using one edge in the same direction (which a
// single orientation cannot fix only with a vertex split, reported by orient()).
void checkManifoldEdges(const TriangleMesh& mesh, const std::string& source) {
  std::vector<std::array<std::uint32_t, 3>> edges;  // (low, high, triangle)
  edges.reserve(mesh.triangles.size() * 3);
  for (std::uint32_t f = 0; f < mesh.triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = mesh.triangles[f][k], b = mesh.triangles[f][(k + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b), f});
    }
  std::sort(edges.begin(), edges.end());
  for (std::size_t i = 0; i + 2 < edges.size(); ++i)
    if (edges[i][0] == edges[i + 2][0] && edges[i][1] == edges[i + 2][1])
      throw MeshError(source, "non-manifold mesh: the edge from " + where(mesh.points[edges[i][0]]) + " to " +
                                  where(mesh.points[edges[i][1]]) + " belongs to more than two triangles (" +
                                  std::to_string(edges[i][2]) + ", " + std::to_string(edges[i + 1][2]) + ", " +
                                  std::to_string(edges[i + 2][2]) + ")");
}

// One orientation per connected part (CGAL), refusing a vertex where separate sheets meet.
void orient(TriangleMesh& mesh, const std::string& source) {
  std::vector<Point> points;
  points.reserve(mesh.points.size());
  for (const Vec3& p : mesh.points) points.emplace_back(p.x(), p.y(), p.z());
  std::vector<std::array<std::size_t, 3>> polygons;
  polygons.reserve(mesh.triangles.size());
  for (const Triangle& t : mesh.triangles) polygons.push_back({t[0], t[1], t[2]});
  const std::size_t before = points.size();
  if (!CGAL::Polygon_mesh_processing::orient_polygon_soup(points, polygons) || points.size() != before) {
    const Vec3 p = points.size() > before ? Vec3(points[before].x(), points[before].y(), points[before].z()) : Vec3::Zero();
    throw MeshError(source, "non-manifold or non-orientable mesh: separate sheets of triangles meet at the vertex " + where(p) +
                                " (or the surface cannot be oriented consistently there)");
  }
  for (std::size_t f = 0; f < polygons.size(); ++f)
    for (int k = 0; k < 3; ++k) mesh.triangles[f][k] = static_cast<std::uint32_t>(polygons[f][k]);
}

}  // namespace

// Each triangle starts at its smallest vertex (cyclic order, so orientation, kept); triangles sorted.
void canonicalizeTriangles(std::vector<Triangle>& triangles) {
  for (Triangle& t : triangles) {
    const int m = static_cast<int>(std::min_element(t.begin(), t.end()) - t.begin());
    std::rotate(t.begin(), t.begin() + m, t.end());
  }
  std::sort(triangles.begin(), triangles.end());
}

// Vertices that are corners of many triangles (a polygon of many corners fanned from its first corner,
// a cone's apex, a UV sphere's pole). CGAL's edge collapse (simplify.cpp) recomputes, after each collapse,
// the cost of every edge at every neighbour of the kept vertex (EdgeCollapse::update_neighbors), and each
// cost walks all triangles at both ends of the edge (Edge_profile::extract_borders on an open mesh, the
// triangles Bounded_normal_change_placement checks): at a vertex of n triangles, n edges of O(n) work
// after each of O(n) collapses nearby, n^3 in all. Measured, simplification alone: a fan of 510 triangles
// 0.57 s, 1,022: 5.0 s, 1,998: 43 s; a double cone, two apexes of 512: 0.89 s, of 812: 3.5 s, of 1,024:
// 7.4 s. 128,000 triangles as fans of 16 triangles: 1.07 s, of 32: 2.2 s, of 64: 4.9 s, where an ordinary
// mesh of 128,000 takes 1.0 s: so vertices of more than 32 triangles count, and the sum of their counts
// cubed may reach 1024^3 (about 5 s, what an ordinary mesh of 350,000 triangles takes): one vertex of up
// to 1,024, or several smaller (a UV sphere of 600 segments passes, with two poles of 600). Scans and
// ordinary meshes have 4 to 12 (the bunny: 10). Accepted meshes are not changed.
constexpr std::uint64_t kCrowdedVertex = 32, kMaxCrowdedVertex = 1024;
constexpr std::uint64_t kMaxCrowdedCubes = kMaxCrowdedVertex * kMaxCrowdedVertex * kMaxCrowdedVertex;

void checkCrowdedVertices(const TriangleMesh& mesh, const std::string& source) {
  std::vector<std::uint64_t> count(mesh.points.size(), 0);
  for (const Triangle& t : mesh.triangles)
    for (std::uint32_t v : t) ++count[v];
  std::uint64_t cubes = 0, crowded = 0;
  std::size_t most = 0;  // the first of the most crowded vertices, in canonical order
  for (std::size_t v = 0; v < count.size(); ++v) {
    if (count[v] > count[most]) most = v;
    if (count[v] <= kCrowdedVertex) continue;
    ++crowded;
    // Saturates instead of overflowing (a count above 1,024 fails anyway).
    cubes = count[v] > kMaxCrowdedVertex ? kMaxCrowdedCubes + 1 : std::min(kMaxCrowdedCubes + 1, cubes + count[v] * count[v] * count[v]);
  }
  if (cubes <= kMaxCrowdedCubes) return;
  throw MeshError(source, "the vertex " + where(mesh.points[most]) + " is a corner of " + std::to_string(count[most]) + " triangles" +
                              (crowded > 1 ? " (and " + std::to_string(crowded - 1) + (crowded == 2 ? " more vertex" : " more vertices") +
                                                 " of more than " + std::to_string(kCrowdedVertex) + ")" : std::string()) +
                              ": simplifying takes time growing as the cube of such counts (5 s at 1,000, 40 s at 2,000); "
                              "rods-from-mesh accepts vertices of up to 1024 triangles, and of those of more than " +
                              std::to_string(kCrowdedVertex) + " at most as many as one of 1024 costs (the sum of their "
                              "counts cubed up to 1024^3). A polygon of many corners is split into a fan from its first "
                              "corner: triangulate it first, or remesh the surface so that no vertex is that crowded");
}

TriangleMesh parseMesh(const std::string& bytes, const std::string& format, const std::string& source, ReadStats& stats) {
  // A changed copy (readerCopy) is counted with the parse before anything is allocated.
  common::requireMemory(bytes.size() * (kParseBytesPerFileByte + 1), {.what = "reading the mesh " + source, .remedy = "simplify the mesh first"});
  if (bytes.find_first_not_of(" \t\r\n") == std::string::npos) throw MeshError(source, "the file is empty: it holds no faces");
  const std::string copy = detail::readerCopy(bytes, format);
  const std::string& text = copy.empty() ? bytes : copy;
  if (format == "off") detail::checkOffText(text, source);
  if (format == "ply") detail::checkPly(text, source);
  if (format == "obj") detail::checkObjFaces(text, source);
  std::vector<Point> points;
  std::vector<Polygon> polygons;
  try {
    if (!readSoup(text, format, points, polygons, source))
      throw MeshError(source, unreadableMeshMessage(text, format, polygons.empty() ? points.size() : 0));
  } catch (const std::bad_alloc&) {
    // The readers size arrays from counts in the file (a face's corner count, an element count).
    throw MeshError(source, "the file declares more elements than the memory budget holds (a count in it is wrong?)");
  }
  if (polygons.empty()) throw MeshError(source, "the file holds no faces");
  common::throwIfInterrupted();
  std::vector<Triangle> triangles = triangulate(points, polygons, source);
  polygons = {};
  // CGAL's STL reader already merges repeated corners: count those as welded too.
  const std::size_t stlMerged = format == "stl" ? 3 * triangles.size() - std::min(3 * triangles.size(), points.size()) : 0;
  common::requireMemory(triangles.size() * kBytesPerTriangle, {.what = "building rods from the mesh " + source,
                                                              .remedy = "simplify the mesh first"});
  TriangleMesh mesh = weld(points, std::move(triangles), stats);
  stats.weldedVertices += stlMerged;
  points = {};
  checkDegenerate(mesh, source);
  checkManifoldEdges(mesh, source);
  common::throwIfInterrupted();
  orient(mesh, source);
  canonicalizeTriangles(mesh.triangles);
  return mesh;
}

TriangleMesh readMesh(const std::filesystem::path& file, ReadStats& stats) {
  detail::requireExtension(file, "mesh", {".stl", ".obj", ".ply", ".off"});
  const std::string format = detail::lowerCaseExtension(file).substr(1);
  const std::uintmax_t size = detail::checkedFileSize(file, ": simplify the mesh first");
  common::requireMemory(size * (kParseBytesPerFileByte + 1), {.what = "reading the mesh " + file.string(),
                                                             .remedy = "simplify the mesh first"});
  std::ifstream in(file, std::ios::binary);
  std::string bytes(size, '\0');
  if (!in || !in.read(bytes.data(), static_cast<std::streamsize>(size)))
    throw MeshError(file, "cannot read the file");
  return parseMesh(bytes, format, file.string(), stats);
}

MeshCounts checkMeshBytes(const std::string& bytes, const std::string& format, const std::string& sourceName) {
  ReadStats stats;
  const TriangleMesh mesh = parseMesh(bytes, format, sourceName, stats);
  return {mesh.points.size(), mesh.triangles.size()};
}

}  // namespace rodfab::meshing
