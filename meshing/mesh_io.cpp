// Mesh files through CGAL's readers, then the checks rodfab relies on: finite coordinates, triangles
// (polygons fanned), welded vertices, no degenerate face, manifold edges and vertices, one orientation;
// and the check rodsFromMesh makes before simplifying, of vertices of so many triangles that it stalls.
#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "common/quoted_text.hpp"
#include "geometry/rod.hpp"
#include "meshing/input_file.hpp"
#include "meshing/mesh.hpp"
#include "meshing/ply_checks.hpp"

#include <CGAL/IO/OBJ.h>
#include <CGAL/IO/OFF.h>
#include <CGAL/IO/PLY.h>
#include <CGAL/IO/STL.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <numeric>
#include <regex>
#include <sstream>
#include <string_view>
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
constexpr const char* kNotFinite = "is not a finite number within the range of a double (about ±1.8e308)";

std::string where(const Vec3& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.6g, %.6g, %.6g)", p.x(), p.y(), p.z());
  return buf;
}

// The next line of `in` that holds something other than a comment, with the comment cut off.
bool nextContentLine(std::istream& in, std::string& line, int& number) {
  while (std::getline(in, line)) {
    ++number;
    line = line.substr(0, line.find('#'));
    if (line.find_first_not_of(" \t\r\x1a") != std::string::npos) return true;  // 0x1a: a DOS end-of-file mark
  }
  return false;
}

// Text OFF is checked before CGAL reads it: its reader sizes arrays from the header's counts, and
// casts each face's corner count from a double to size_t unchecked (undefined behaviour for 1e114 or
// -1, found by fuzzing), and reads a face's colour from the entries after its corners without checking
// they are there (a heap overflow when a line holds fewer numbers than its corner count says, found by
// fuzzing). So: counts the file's bytes can hold (a vertex takes at least 6 bytes of text, a face 8);
// every vertex line holds at least 3 numbers; every face line starts with a corner count of 3 to
// 1,000,000 and holds that many indices of existing vertices (CGAL casts them unchecked too) plus 0, 1,
// 3 or 4 colour entries. Vertex lines are taken one per line, as every OFF writer puts them.
void checkOffText(const std::string& bytes, const std::string& source) {
  std::istringstream in(bytes);
  std::string line;
  int number = 0;
  if (!nextContentLine(in, line, number)) return;
  std::istringstream head(line);
  std::string word, rest;
  head >> word;
  // CGAL takes any first word holding "OFF", even with bytes glued to it, and "SKEL" (a skeleton of
  // polylines, read unchecked: a polyline of 500 M points took 18 s and 3.9 GB); only the standard
  // keywords ([ST][C][N][4][n]OFF) are let through, so this check reads the counts where CGAL does.
  if (!std::regex_match(word, std::regex("(ST)?C?N?4?n?OFF")))
    throw MeshError(source, "OFF line " + std::to_string(number) + ": " + common::quotedFromFile(word) + " is not an OFF keyword");
  // nOFF puts a dimension before the counts, which CGAL reads as integers while this check read the
  // counts from it (a face of 5e10 corners reached CGAL: fuzz_mesh_reader, 2026-12-05); meshes here are 3D.
  if (word.find('n') != std::string::npos)
    throw MeshError(source, "OFF line " + std::to_string(number) + ": " + common::quotedFromFile(word) +
                                " (OFF of n dimensions) is not read: rods need a 3D mesh; write it as OFF");
  if (!(head >> rest) && !(nextContentLine(in, line, number) && (head = std::istringstream(line), head >> rest))) return;
  if (rest == "BINARY") return;  // binary counts: CGAL reads them as integers
  // The counts as every OFF writer puts them: vertices, faces, edges on one line (CGAL reads them as
  // tokens across lines, which would put this check out of step with it).
  double nv = -1, nf = -1, ne = -1;
  std::string extra;
  if (!(std::istringstream(rest) >> nv) || !(head >> nf >> ne) || (head >> extra) || nv != std::floor(nv) ||
      nf != std::floor(nf) || ne != std::floor(ne))
    throw MeshError(source, "OFF line " + std::to_string(number) + ": expected the vertex, face and edge counts on one line");
  if (nv < 0 || nf < 0 || nv * 6 + nf * 8 > static_cast<double>(bytes.size()) + 64)
    throw MeshError(source, "the OFF header declares " + rest + " vertices and more faces than the file's " +
                                std::to_string(bytes.size()) + " bytes can hold");
  const auto where = [&] { return "OFF line " + std::to_string(number) + ": "; };
  // The line's leading numbers, as CGAL's stream reads them; one it cannot hold is named.
  auto numbers = [&](const std::string& text) {
    std::istringstream words(text);
    std::vector<double> out;
    for (std::string token; words >> token;) {
      char* end = nullptr;
      const double d = std::strtod(token.c_str(), &end);
      if (end == token.c_str()) break;
      if (!std::isfinite(d)) throw MeshError(source, where() + common::quotedFromFile(token) + " " + kNotFinite);
      out.push_back(d);
    }
    return out;
  };
  for (double v = 0; v < nv; ++v) {
    if (!nextContentLine(in, line, number)) return;
    if (numbers(line).size() < 3) throw MeshError(source, where() + "a vertex needs 3 coordinates");
  }
  double facesRead = 0;
  for (; facesRead < nf && nextContentLine(in, line, number); ++facesRead) {
    const std::vector<double> entries = numbers(line);
    const double corners = entries.empty() ? 0 : entries[0];
    if (!(corners >= 3 && corners <= 1e6) || corners != std::floor(corners))
      throw MeshError(source, where() + "a face's corner count must be a whole number from 3 to 1000000");
    for (std::size_t k = 1; k <= static_cast<std::size_t>(corners) && k < entries.size(); ++k)
      if (!(entries[k] >= 0 && entries[k] < nv) || entries[k] != std::floor(entries[k]))
        throw MeshError(source, where() + "a face refers to a vertex that is not one of the " + rest);
    const double colours = static_cast<double>(entries.size()) - 1 - corners;
    if (colours != 0 && colours != 1 && colours != 3 && colours != 4)
      throw MeshError(source, where() + "a face of " + std::to_string(static_cast<long>(corners)) + " corners needs as many " +
                                  "indices (and 0, 1, 3 or 4 colour entries)");
  }
  // CGAL stops at the declared count: faces past it (a stale count) were dropped without a word.
  if (facesRead == nf && nextContentLine(in, line, number))
    throw MeshError(source, where() + "more lines follow the " + std::to_string(static_cast<long long>(nf)) +
                                " faces the header declares: its face count is smaller than the file's (nothing was read)");
}

// Calls f(line) for every line of `bytes`, without its line break and trailing white space.
template <typename F>
void forEachLine(std::string_view bytes, const F& f) {
  while (!bytes.empty()) {
    const std::size_t eol = std::min(bytes.find('\n'), bytes.size());
    std::string_view line = bytes.substr(0, eol);
    line = line.substr(0, line.find_last_not_of(" \t\r") + 1);
    f(line);
    bytes.remove_prefix(std::min(eol + 1, bytes.size()));
  }
}

// A line's first word (CGAL's `iss >> s`) and what follows it.
std::pair<std::string_view, std::string_view> keyword(std::string_view line) {
  const std::size_t begin = std::min(line.find_first_not_of(" \t\r"), line.size());
  const std::size_t end = std::min(line.find_first_of(" \t\r", begin), line.size());
  return {line.substr(begin, end - begin), line.substr(end)};
}

// CGAL's OBJ reader reads a face's corners as `int`s, each up to the next space, and stops at the
// first one it cannot read: a vertex number past 2^31 or a word silently shortens the face, and a number
// beyond the vertices only fails the whole file. Every face line is checked the way that reader takes
// it (tabs are spaces by then: see parseMesh), so the message names the line and the corner.
void checkObjFaces(const std::string& bytes, const std::string& source) {
  std::uint64_t vertices = 0, seen = 0;
  forEachLine(bytes, [&](std::string_view line) { vertices += keyword(line).first == "v"; });
  int number = 0;
  forEachLine(bytes, [&](std::string_view line) {
    ++number;
    auto [word, rest] = keyword(line);
    seen += word == "v";
    if (word != "f") return;
    const auto where = [&] { return "OBJ line " + std::to_string(number) + ": "; };
    rest = rest.substr(0, rest.find('#'));
    rest.remove_prefix(std::min(rest.find_first_not_of(" \t\r"), rest.size()));
    int corners = 0;
    for (std::size_t at = 0; (at = rest.find_first_not_of(" \r", at)) != std::string_view::npos; ++corners) {
      std::string_view corner = rest.substr(at, rest.find(' ', at) - at);
      at += corner.size();
      const std::string shown = common::quotedFromFile(corner);
      if (corner.starts_with('+')) corner.remove_prefix(1);
      long long index = 0;
      const auto [end, error] = std::from_chars(corner.data(), corner.data() + corner.size(), index);
      if (end == corner.data() || (error == std::errc{} && end != corner.data() + corner.size() && *end != '/'))
        throw MeshError(source, where() + "face corner " + shown + " is not a vertex number");
      if (error != std::errc{} || index == 0 || index > std::numeric_limits<int>::max() ||
          (index > 0 && std::uint64_t(index) > vertices) || (index < 0 && std::uint64_t(-index) > seen))
        throw MeshError(source, where() + "face corner " + shown + " names no vertex: expected 1 .. " + std::to_string(vertices) +
                                    " (or -1 .. -" + std::to_string(seen) + ", counted back from this line)");
    }
    if (corners < 3) throw MeshError(source, where() + "a face with " + std::to_string(corners) + " corners (expected 3 or more)");
  });
}

// Text STL starts with "solid" and is text throughout; a binary header may start with "solid" too, but
// its triangles' floats soon hold bytes no text has.
bool looksLikeTextStl(const std::string& bytes) {
  const std::size_t begin = std::min(bytes.find_first_not_of(" \t\r\n"), bytes.size());
  if (bytes.compare(begin, 5, "solid") != 0) return false;
  const std::size_t end = std::min<std::size_t>(bytes.size(), 1024);
  return std::none_of(bytes.begin() + static_cast<std::ptrdiff_t>(begin), bytes.begin() + static_cast<std::ptrdiff_t>(std::max(begin, end)), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u == 0 || (u < 32 && !std::isspace(u)) || u == 127;
  });
}

// CGAL's STL reader merges corners through an ordered map, which a NaN corrupts (it compares equal to
// everything): check a binary STL's floats before it is read.
void checkBinaryStlNumbers(const std::string& bytes, const std::string& source) {
  if (bytes.size() < 84 || looksLikeTextStl(bytes)) return;
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  const std::uint64_t declared = 84 + 50 * std::uint64_t(count);
  // CGAL reads `count` triangles and ignores the rest: triangles past a stale count were dropped
  // without a word, and a truncated file failed saying nothing of why. A few bytes of padding pass.
  if (bytes.size() < declared || bytes.size() >= declared + 50)
    throw MeshError(source, std::string(bytes.compare(0, 5, "solid") == 0 ? "neither a text STL (it starts with \"solid\" but holds bytes "
                                                                           "no text has) nor a " : "") +
                                "binary STL: its header declares " + std::to_string(count) + " triangles (" + std::to_string(declared) +
                                " bytes), but the file holds " + std::to_string(bytes.size()) + " bytes: " +
                                (bytes.size() > declared ? "the count is smaller than the data" : "was it cut short?") + " (nothing was read)");
  for (std::uint32_t t = 0; t < count; ++t)
    for (int k = 3; k < 12; ++k) {  // the 9 corner coordinates after the normal
      float v = 0;
      std::memcpy(&v, bytes.data() + 84 + 50 * std::size_t(t) + 4 * k, 4);
      if (!std::isfinite(v))
        throw MeshError(source, "triangle " + std::to_string(t) + " has a coordinate that is not a finite number");
    }
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
        return "line " + std::to_string(number) + ": '" + token.substr(0, 40) + "' " + kNotFinite;
    }
  }
  return generic;
}

bool readSoup(const std::string& bytes, const std::string& format, std::vector<Point>& points,
              std::vector<Polygon>& polygons, const std::string& source) {
  if (format == "stl") checkBinaryStlNumbers(bytes, source);
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

constexpr std::string_view kUtf8Mark = "\xEF\xBB\xBF";

// What CGAL's readers would misread, changed in a copy (empty when nothing needs to change): a UTF-8
// byte order mark before a text format (it glued to the first keyword: vertex 1 was lost, and a face
// 99 lines on was blamed); in OBJ, tabs (its reader skips a face corner up to the next space, so a
// tab-separated face lost corners) and line elements "l" (polylines, no surface: the reader failed the
// whole file), made comments.
std::string readerCopy(const std::string& bytes, const std::string& format) {
  // A text STL's mark too (its "solid" then read as a binary count); never a binary STL's header bytes.
  const bool mark = bytes.starts_with(kUtf8Mark) && (format != "stl" || looksLikeTextStl(bytes.substr(kUtf8Mark.size(), 1024)));
  const std::string_view body = std::string_view(bytes).substr(mark ? kUtf8Mark.size() : 0);
  const bool obj = format == "obj";
  const bool tabs = obj && body.find('\t') != std::string_view::npos;
  bool lines = false;  // a line whose first word (as CGAL reads it, after blanks) is "l"
  if (obj) forEachLine(body, [&](std::string_view line) { lines = lines || keyword(line).first == "l"; });
  if (!mark && !tabs && !lines) return {};
  std::string text(body);
  if (tabs) std::replace(text.begin(), text.end(), '\t', ' ');
  if (lines)
    for (std::size_t at = 0; at < text.size(); at = std::min(text.find('\n', at), text.size()) + 1) {
      const std::size_t word = std::min(text.find_first_not_of(" \r", at), text.size());
      if (text.compare(word, 2, "l ") == 0 || (text.compare(word, 1, "l") == 0 && (word + 1 == text.size() || text[word + 1] == '\n')))
        text[word] = '#';
    }
  return text;
}

TriangleMesh parseMesh(const std::string& bytes, const std::string& format, const std::string& source, ReadStats& stats) {
  // A changed copy (readerCopy) is counted with the parse before anything is allocated.
  common::requireMemory(bytes.size() * (kParseBytesPerFileByte + 1), {.what = "reading the mesh " + source, .remedy = "simplify the mesh first"});
  if (bytes.find_first_not_of(" \t\r\n") == std::string::npos) throw MeshError(source, "the file is empty: it holds no faces");
  const std::string copy = readerCopy(bytes, format);
  const std::string& text = copy.empty() ? bytes : copy;
  if (format == "off") checkOffText(text, source);
  if (format == "ply") detail::checkPly(text, source);
  if (format == "obj") checkObjFaces(text, source);
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
