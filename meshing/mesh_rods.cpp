// The dual of the simplified mesh, laid on the original surface: nodes, rods, the surface check.
#include "common/interrupt.hpp"
#include "common/stopwatch.hpp"
#include "meshing/mesh.hpp"

#include <boost/math/tools/minima.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <exception>
#include <optional>
#include <limits>
#include <numeric>

namespace rodfab::meshing {

MeshError::MeshError(const std::filesystem::path& file, const std::string& message)
    : std::runtime_error(file.string() + ": " + message), file_(file) {}

namespace {

// Centerline points checked against the surface per knot span.
constexpr int kChecksPerSpan = 16;
// Sample counts tried per rod: subdivisions, doubled up to this factor or kMaxSamples.
constexpr int kMaxRefinementFactor = 16;
constexpr int kMaxSamples = 256;
// Bisections that close one gap left by the projection (2^6 points at most).
constexpr int kGapDepth = 6;

struct Node {
  Vec3 point, normal;
};

// An interior edge (a, b) of the simplified mesh and its two faces f < g.
struct DualEdge {
  std::uint32_t a, b, f, g;
};

struct Dual {
  std::vector<DualEdge> edges;
  std::size_t boundaryEdges = 0;
};

Dual buildDual(const TriangleMesh& mesh) {
  std::vector<std::array<std::uint32_t, 3>> halfEdges;  // (low, high, face)
  for (std::uint32_t f = 0; f < mesh.triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = mesh.triangles[f][k], b = mesh.triangles[f][(k + 1) % 3];
      halfEdges.push_back({std::min(a, b), std::max(a, b), f});
    }
  std::sort(halfEdges.begin(), halfEdges.end());
  Dual dual;
  for (std::size_t i = 0; i < halfEdges.size();) {
    const auto& e = halfEdges[i];
    if (i + 1 < halfEdges.size() && halfEdges[i + 1][0] == e[0] && halfEdges[i + 1][1] == e[1]) {
      dual.edges.push_back({e[0], e[1], e[2], halfEdges[i + 1][2]});
      i += 2;
    } else {
      ++dual.boundaryEdges;
      ++i;
    }
  }
  return dual;
}

Vec3 centroid(const TriangleMesh& mesh, std::uint32_t f) {
  const Triangle& t = mesh.triangles[f];
  return (mesh.points[t[0]] + mesh.points[t[1]] + mesh.points[t[2]]) / 3.0;
}

Vec3 faceNormal(const TriangleMesh& mesh, std::uint32_t f) {
  const Triangle& t = mesh.triangles[f];
  return (mesh.points[t[1]] - mesh.points[t[0]]).cross(mesh.points[t[2]] - mesh.points[t[0]]).normalized();
}

// Appends the points strictly between a and b that close a gap: closest-point projection jumps across
// a crease (points inside a convex edge go to one face or the other), leaving two data points far apart
// with the crease between them; projected midpoints, bisected while the gap exceeds `spacing`, walk
// onto the crease so the interpolant follows it.
void fillGap(const SurfaceProjector& surface, const Vec3& a, const Vec3& b, double spacing, int depth, std::vector<Vec3>& out) {
  if (depth == 0 || (b - a).norm() <= spacing) return;
  const Vec3 m = surface.closest(0.5 * (a + b)).point;
  if ((m - a).norm() <= 1e-9 * spacing || (m - b).norm() <= 1e-9 * spacing) return;
  fillGap(surface, a, m, spacing, depth - 1, out);
  out.push_back(m);
  fillGap(surface, m, b, spacing, depth - 1, out);
}

// Where the rod crosses the shared edge ab, as a fraction of ab: the shortest path from c0 over ab to
// c1 (the two faces unfolded into one plane, the straight line c0 -> c1 meets ab where it divides the
// centroids' feet on ab in the ratio of their distances from it). Through the edge's midpoint the path
// turned by up to ~90 degrees there wherever the two faces were not point-symmetric about it, and the
// interpolant bent tighter than the rod's section. Kept a quarter of the edge away from its corners so the
// rods around one vertex stay apart (the shortest path of an obtuse pair would run through the vertex).
double shortestCrossing(const Vec3& c0, const Vec3& c1, const Vec3& a, const Vec3& b) {
  constexpr double kCornerMargin = 0.25;
  const Vec3 ab = b - a;
  const double t0 = (c0 - a).dot(ab) / ab.squaredNorm(), t1 = (c1 - a).dot(ab) / ab.squaredNorm();
  const double d0 = (c0 - a - t0 * ab).norm(), d1 = (c1 - a - t1 * ab).norm();
  const double t = d0 + d1 > 0 ? t0 + (t1 - t0) * d0 / (d0 + d1) : 0.5;
  return std::clamp(t, kCornerMargin, 1.0 - kCornerMargin);
}

// The rod's path over its two faces: the quadratic Bezier curve from centroid c0 to centroid c1 whose
// control point is the edge crossing, walked by arc length. On a flat pair of faces whose shortest
// path crosses within the edge's middle half, the three points are in line and the path is that
// straight segment. Where the crossing is held back from a corner, the polyline c0 -> crossing -> c1
// turned there, and the interpolant through points on it bent about as tight as their spacing (a flat
// 50 mm plate at --faces 1000: 164 of its rods tighter than a 1 mm rod's section, down to 0.002 mm);
// the curve turns gradually instead, no tighter than a fraction of its legs' length.
class CrossingPath {
public:
  CrossingPath(const Vec3& c0, const Vec3& crossing, const Vec3& c1) : c0_(c0), crossing_(crossing), c1_(c1) {
    lengths_[0] = 0.0;
    for (int i = 1; i <= kChords; ++i) lengths_[i] = lengths_[i - 1] + (at(double(i) / kChords) - at(double(i - 1) / kChords)).norm();
  }
  double length() const { return lengths_[kChords]; }
  // The point `s` (0 <= s <= length()) along the path, by the arc length of its chords.
  Vec3 pointAt(double s) const {
    const int i = int(std::upper_bound(lengths_.begin(), lengths_.end(), s) - lengths_.begin()) - 1;
    if (i >= kChords) return c1_;
    const double span = lengths_[i + 1] - lengths_[i];
    const double f = span > 0.0 ? (s - lengths_[i]) / span : 0.0;
    return at((i + f) / kChords);
  }

private:
  static constexpr int kChords = 64;  // steps measured along 64 chords: even enough for sampling
  Vec3 at(double t) const { return (1 - t) * (1 - t) * c0_ + 2 * t * (1 - t) * crossing_ + t * t * c1_; }
  Vec3 c0_, crossing_, c1_;
  std::array<double, kChords + 1> lengths_{};
};

// The data points of one rod: node f, `count` points at equal steps along the CrossingPath over the
// shared edge (on the simplified surface) moved to the original surface, gaps filled, node g.
std::vector<Vec3> rodSamples(const TriangleMesh& simplified, const SurfaceProjector& surface, const DualEdge& e,
                             const std::vector<Node>& nodes, int count) {
  const Vec3 c0 = centroid(simplified, e.f), c1 = centroid(simplified, e.g);
  const Vec3 &a = simplified.points[e.a], &b = simplified.points[e.b];
  const CrossingPath path(c0, a + (b - a) * shortestCrossing(c0, c1, a, b), c1);
  const double length = path.length();
  std::vector<Vec3> projected{nodes[e.f].point};
  for (int i = 1; i <= count; ++i) projected.push_back(surface.closest(path.pointAt(length * i / (count + 1))).point);
  projected.push_back(nodes[e.g].point);
  const double spacing = 1.5 * length / (count + 1);
  std::vector<Vec3> points{projected.front()};
  for (std::size_t i = 1; i < projected.size(); ++i) {
    fillGap(surface, points.back(), projected[i], spacing, kGapDepth, points);
    // Where the original surface folds, two samples can land on one point: keep the first.
    if ((projected[i] - points.back()).norm() > 1e-9 * length) points.push_back(projected[i]);
    else if (i + 1 == projected.size()) points.back() = projected[i];  // the node itself ends the rod
  }
  return points;
}

struct FitMeasures {
  double surfaceDistance = 0;                                       // mm, largest
  double bendRadius = std::numeric_limits<double>::infinity();      // mm, smallest radius of curvature
};

// The centerline's largest distance from the surface: sampled at kChecksPerSpan + 1 points of every
// knot span, then each sample that is a local maximum within 0.7 of the largest narrowed between its
// neighbours by Brent's method (Boost.Math, as calibration's fit): the samples alone read 4 to 15 %
// low (a rod said to be within 0.0275 mm of an icosphere reached 0.0316 mm between them).
double largestSurfaceDistance(const geometry::NurbsCurve& curve, const SurfaceProjector& surface) {
  const std::vector<double> breaks = curve.breakpoints();
  std::vector<double> us, distances;
  for (std::size_t s = 0; s + 1 < breaks.size(); ++s)
    for (int i = s == 0 ? 0 : 1; i <= kChecksPerSpan; ++i) us.push_back(breaks[s] + (breaks[s + 1] - breaks[s]) * i / kChecksPerSpan);
  const auto distance = [&](double u) { return surface.distance(curve.point(u)); };
  for (double u : us) distances.push_back(distance(u));
  const double sampled = *std::max_element(distances.begin(), distances.end());
  double largest = sampled;
  if (!(sampled > 0)) return largest;  // on the surface throughout (a flat mesh): nothing to narrow
  for (std::size_t i = 0; i < us.size(); ++i) {
    const bool peak = (i == 0 || distances[i] > distances[i - 1]) && (i + 1 == us.size() || distances[i] >= distances[i + 1]);
    if (!peak || distances[i] < 0.7 * sampled) continue;
    std::uintmax_t iterations = 40;
    const auto farthest = boost::math::tools::brent_find_minima([&](double u) { return -distance(u); }, us[i > 0 ? i - 1 : 0],
                                                                us[std::min(i + 1, us.size() - 1)], std::numeric_limits<double>::digits / 2,
                                                                iterations);
    largest = std::max(largest, -farthest.second);
  }
  return largest;
}

// The centerline's largest distance from the surface and its smallest radius of curvature (at
// kChecksPerSpan + 1 points of every knot span).
FitMeasures measureFit(const geometry::NurbsCurve& curve, const SurfaceProjector& surface) {
  FitMeasures m;
  m.surfaceDistance = largestSurfaceDistance(curve, surface);
  m.bendRadius = smallestBendRadius(curve, kChecksPerSpan);
  return m;
}

// interpolateCubic through the rod's samples; a failure is the mesh's, named with the rod's faces.
geometry::NurbsCurve interpolateCurve(const std::vector<Vec3>& points, const DualEdge& e, const std::filesystem::path& file) {
  try {
    return interpolateCubic(points);
  } catch (const std::invalid_argument& error) {
    throw MeshError(file, "the rod between the faces " + std::to_string(e.f) + " and " + std::to_string(e.g) +
                              " of the simplified mesh cannot be fitted (" + error.what() + "): ask for other --faces");
  }
}

struct FittedRod {
  geometry::NurbsCurve curve;
  FitMeasures measures;
  bool refined = false;
  bool closerFitBentTighter = false;  // a fit closer to the surface was refused: it bent tighter than the section
};

// Whether fit a is better than fit b: one that bends no tighter than the section first (a rod folding
// over itself is a defect, a rod off a faceted surface by less than its thickness is not), then the
// closer to the surface, or among fits that all bend tighter, the gentler.
bool betterFit(const FitMeasures& a, const FitMeasures& b, double sectionRadius) {
  const bool aSmooth = a.bendRadius >= sectionRadius, bSmooth = b.bendRadius >= sectionRadius;
  if (aSmooth != bSmooth) return aSmooth;
  return aSmooth ? a.surfaceDistance < b.surfaceDistance : a.bendRadius > b.bendRadius;
}

// Interpolates the rod with `subdivisions` samples, doubling them while the centerline leaves the
// surface by more than the tolerance (up to kMaxRefinementFactor times), and keeps the best fit
// (betterFit): on a creased surface the samples that follow the facets closer bend the rod at the creases.
FittedRod fitRod(const TriangleMesh& simplified, const SurfaceProjector& surface, const DualEdge& e,
                 const std::vector<Node>& nodes, const MeshRodOptions& options, const std::filesystem::path& file) {
  const double sectionRadius = options.section.boundingRadius();
  FittedRod best;
  for (int factor = 1; factor <= kMaxRefinementFactor && options.subdivisions * factor <= std::max(kMaxSamples, options.subdivisions); factor *= 2) {
    const std::vector<Vec3> points = rodSamples(simplified, surface, e, nodes, options.subdivisions * factor);
    if (points.size() < 4)
      throw MeshError(file, "the surface folds onto itself between the faces " + std::to_string(e.f) + " and " +
                                std::to_string(e.g) + " of the simplified mesh: ask for more --faces");
    geometry::NurbsCurve curve = interpolateCurve(points, e, file);
    const FitMeasures measures = measureFit(curve, surface);
    if (factor == 1 || betterFit(measures, best.measures, sectionRadius)) {
      best.curve = std::move(curve), best.measures = measures, best.refined = factor > 1;
    } else if (measures.surfaceDistance < best.measures.surfaceDistance) {
      best.closerFitBentTighter = true;
    }
    if (best.measures.surfaceDistance <= options.surfaceTolerance && best.measures.bendRadius >= sectionRadius) break;
  }
  best.closerFitBentTighter = best.closerFitBentTighter && best.measures.surfaceDistance > options.surfaceTolerance;
  return best;
}

// The surface normal at the rod's first node, or the simplified face's normal where the surface's
// normal lies too close to the centerline's tangent to seed a frame.
// Where both lie along the tangent (a rod crossing the rim of a plate thinner than its faces are wide:
// 1e-7 mm, every rim face's normal along the rod), the coordinate axis most across the tangent, made
// perpendicular: the design was refused, "the reference normal is parallel to the centerline's tangent"
// of a rod the user never drew.
Vec3 referenceNormal(const geometry::NurbsCurve& curve, const Node& node, const Vec3& faceNormal) {
  Vec3 d[2];
  curve.derivatives(curve.domainBegin(), 1, d);
  const Vec3 t = d[1].normalized();
  for (const Vec3& n : {node.normal, faceNormal})
    if (std::abs(n.dot(t)) < 0.9) return n;
  Eigen::Index axis = 0;
  t.cwiseAbs().minCoeff(&axis);
  return (Vec3::Unit(axis) - t * t[axis]).normalized();
}

std::size_t countComponents(std::size_t faces, const std::vector<DualEdge>& edges) {
  std::vector<std::uint32_t> parent(faces);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  std::vector<bool> used(faces, false);
  for (const DualEdge& e : edges) {
    parent[find(e.f)] = find(e.g);
    used[e.f] = used[e.g] = true;
  }
  std::size_t count = 0;
  for (std::uint32_t f = 0; f < faces; ++f) count += used[f] && find(f) == f;
  return count;
}

std::vector<Node> projectNodes(const TriangleMesh& simplified, const SurfaceProjector& surface) {
  std::vector<Node> nodes(simplified.triangles.size());
  tbb::parallel_for(std::size_t(0), nodes.size(), [&](std::size_t f) {
    const SurfaceProjector::Hit hit = surface.closest(centroid(simplified, static_cast<std::uint32_t>(f)));
    nodes[f] = {hit.point, hit.normal};
  });
  return nodes;
}

// One rod of the dual, fitted and built on a worker. A rod that cannot be made keeps what it threw:
// the lowest-numbered rod's failure is the one reported, whatever the thread count.
struct BuiltRod {
  FitMeasures measures;
  bool refined = false, closerFitBentTighter = false;
  std::optional<geometry::Rod> rod;
  std::exception_ptr failure;
};

// Where the mesh is worked on: its own bounding box's centre when that lies farther from the origin
// than the box's diagonal (a sphere 1e8 mm out fitted 80 rods bending at 0.007 mm, centred none),
// else the origin itself, so a mesh around the origin is worked on as it is, to the bit.
Vec3 workingOrigin(const TriangleMesh& mesh) {
  Eigen::AlignedBox3d box;
  for (const Vec3& p : mesh.points) box.extend(p);
  if (box.isEmpty()) return Vec3::Zero();
  return box.center().norm() > box.diagonal().norm() ? Vec3(box.center()) : Vec3::Zero();
}

TriangleMesh translated(TriangleMesh mesh, const Vec3& by) {
  if (by.isZero(0.0)) return mesh;
  for (Vec3& p : mesh.points) p += by;
  return mesh;
}

geometry::NurbsCurve translated(const geometry::NurbsCurve& curve, const Vec3& by) {
  if (by.isZero(0.0)) return curve;
  std::vector<Vec3> points = curve.points();
  for (Vec3& p : points) p += by;
  return geometry::NurbsCurve(curve.degree(), curve.knots(), std::move(points), curve.weights());
}

BuiltRod buildRod(std::size_t i, const TriangleMesh& simplified, const SurfaceProjector& surface, const DualEdge& e,
                  const std::vector<Node>& nodes, const MeshRodOptions& options, const std::filesystem::path& file,
                  const Vec3& origin) {
  BuiltRod out;
  try {
    FittedRod fit = fitRod(simplified, surface, e, nodes, options, file);
    fit.curve = translated(fit.curve, origin);  // fitted about the working origin, placed where the mesh is
    out.measures = fit.measures, out.refined = fit.refined, out.closerFitBentTighter = fit.closerFitBentTighter;
    const Vec3 normal = referenceNormal(fit.curve, nodes[e.f], faceNormal(simplified, e.f));
    try {
      out.rod.emplace("rod-" + std::to_string(i), std::move(fit.curve), options.section, normal, std::nullopt, options.caps,
                      geometry::BSplineField::constant(options.modulusMpa, 0.0, 1.0));
    } catch (const geometry::CenterlineError& error) {  // a mesh at the scale of 1e-12 mm: as requireValidDesign says it
      throw MeshError(file, "rod-" + std::to_string(i) + ", as rods[" + std::to_string(i) + "].centerline: " + error.what() +
                                "; the design would not be valid");
    }
  } catch (...) {
    out.failure = std::current_exception();
  }
  return out;
}

geometry::RodStructure buildRods(const std::filesystem::path& file, const TriangleMesh& original,
                                 const TriangleMesh& simplified, const MeshRodOptions& options, MeshRodReport& report,
                                 const Vec3& origin) {
  const SurfaceProjector surface(original);
  common::throwIfInterrupted();
  const Dual dual = buildDual(simplified);
  report.boundaryEdges = dual.boundaryEdges;
  if (dual.edges.empty()) throw MeshError(file, "no two faces of the simplified mesh share an edge, so there is no rod");
  const std::vector<Node> nodes = projectNodes(simplified, surface);
  // The rods are built on the workers too (their sampling and frames were 90 % of the serial time).
  std::vector<BuiltRod> built(dual.edges.size());
  tbb::parallel_for(std::size_t(0), built.size(), [&](std::size_t i) {
    if (common::interruptRequested()) return;
    built[i] = buildRod(i, simplified, surface, dual.edges[i], nodes, options, file, origin);
  });
  common::throwIfInterrupted();
  for (const BuiltRod& b : built)
    if (b.failure) std::rethrow_exception(b.failure);
  geometry::RodStructure structure;
  structure.rods.reserve(built.size());
  std::vector<bool> isNode(nodes.size(), false);
  for (std::size_t i = 0; i < built.size(); ++i) {
    const DualEdge& e = dual.edges[i];
    const BuiltRod& b = built[i];
    report.largestSurfaceDistance = std::max(report.largestSurfaceDistance, b.measures.surfaceDistance);
    report.refinedRods += b.refined;
    report.rodsAboveTolerance += b.measures.surfaceDistance > options.surfaceTolerance;
    report.rodsHeldOffCreases += b.closerFitBentTighter;
    report.smallestBendRadius = std::min(report.smallestBendRadius, b.measures.bendRadius);
    report.rodsBentTighterThanSection += b.measures.bendRadius < options.section.boundingRadius();
    isNode[e.f] = isNode[e.g] = true;
    structure.rods.push_back(std::move(*built[i].rod));
  }
  report.rods = structure.rods.size();
  report.nodes = static_cast<std::size_t>(std::count(isNode.begin(), isNode.end(), true));
  report.components = countComponents(nodes.size(), dual.edges);
  return structure;
}

void checkOptions(const MeshRodOptions& o) {
  if (o.faces < kMinFaces || o.faces > kMaxFaces) throw std::invalid_argument("rodsFromMesh: faces out of range");
  if (o.subdivisions < kMinSubdivisions || o.subdivisions > kMaxSubdivisions)
    throw std::invalid_argument("rodsFromMesh: subdivisions out of range");
  if (!(o.surfaceTolerance > 0) || !std::isfinite(o.surfaceTolerance))
    throw std::invalid_argument("rodsFromMesh: surface tolerance must be > 0");
  if (!(o.modulusMpa > 0) || !std::isfinite(o.modulusMpa)) throw std::invalid_argument("rodsFromMesh: modulus must be > 0");
}

}  // namespace

MeshRods rodsFromMesh(const std::filesystem::path& file, const MeshRodOptions& options) {
  checkOptions(options);
  MeshRods out;
  MeshRodReport& report = out.report;
  auto clock = std::chrono::steady_clock::now();
  ReadStats stats;
  TriangleMesh original = readMesh(file, stats);
  report.inputVertices = original.points.size(), report.inputFaces = original.triangles.size();
  report.weldedVertices = stats.weldedVertices;
  if (original.triangles.size() < static_cast<std::size_t>(options.faces))
    throw MeshError(file, "the mesh has " + std::to_string(original.triangles.size()) +
                              (original.triangles.size() == 1 ? " triangle" : " triangles") + ", fewer than the " +
                              std::to_string(options.faces) + " asked for (--faces)");
  report.readSeconds = common::secondsSince(clock);
  clock = std::chrono::steady_clock::now();
  const bool simplifies = original.triangles.size() != static_cast<std::size_t>(options.faces);
  if (simplifies) checkCrowdedVertices(original, file.string());  // before, not minutes into, the simplification
  const Vec3 origin = workingOrigin(original);  // after the check, which names a vertex where the file has it
  original = translated(std::move(original), -origin);
  const TriangleMesh simplified = simplifies ? simplifyMesh(original, options.faces) : original;
  report.simplifiedVertices = simplified.points.size(), report.simplifiedFaces = simplified.triangles.size();
  report.requestedFaces = static_cast<std::size_t>(options.faces);
  report.simplifySeconds = common::secondsSince(clock);
  clock = std::chrono::steady_clock::now();
  out.structure = buildRods(file, original, simplified, options, report, origin);
  out.structure.source = file.string();
  requireValidDesign(out.structure, file, [](std::size_t rod) { return "rod-" + std::to_string(rod); });
  report.rodSeconds = common::secondsSince(clock);
  return out;
}

}  // namespace rodfab::meshing
