// meshing/ internals: the triangle mesh passed between the reader, the simplifier, the surface
// projector and the rod builder. CGAL stays inside the .cpp files that need it.
#pragma once

#include "geometry/nurbs.hpp"
#include "meshing/meshing.hpp"

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace rodfab::meshing {

using geometry::Vec3;
using Triangle = std::array<std::uint32_t, 3>;

// An oriented, manifold, welded triangle mesh (what readMesh guarantees): vertices sorted
// lexicographically, each triangle rotated to start at its smallest index, triangles sorted, so the
// same surface gives the same mesh from any file format or vertex order.
struct TriangleMesh {
  std::vector<Vec3> points;
  std::vector<Triangle> triangles;
};

struct ReadStats {
  std::size_t weldedVertices = 0;
};

// Rotates each triangle to start at its smallest vertex (orientation kept) and sorts the triangles.
void canonicalizeTriangles(std::vector<Triangle>& triangles);

// Reads and checks a mesh file (see rodsFromMesh for the errors).
TriangleMesh readMesh(const std::filesystem::path& file, ReadStats& stats);
// The same on bytes in memory; `format` is the lower-case extension, `source` names it in errors.
TriangleMesh parseMesh(const std::string& bytes, const std::string& format, const std::string& source, ReadStats& stats);

// Throws MeshError (naming `source`) when a vertex of `mesh` is a corner of so many triangles that
// simplifyMesh would stall (its cost grows as the cube of the count: meshing/README.md, "Crowded
// vertices"): more than 1,024 at one vertex, or vertices of more than 32 whose counts cubed sum past
// 1024^3. rodsFromMesh calls it before simplifying; a mesh that is not simplified may have them.
void checkCrowdedVertices(const TriangleMesh& mesh, const std::string& source);

// Edge-collapse simplification to about `targetFaces` triangles (CGAL Garland-Heckbert plane quadrics
// with its default placement). The result is manifold and oriented like the input, canonical as above.
TriangleMesh simplifyMesh(const TriangleMesh& mesh, std::size_t targetFaces);

// Closest points on a triangle mesh (CGAL AABB tree). Queries are const and thread-safe.
class SurfaceProjector {
public:
  explicit SurfaceProjector(const TriangleMesh& mesh);
  ~SurfaceProjector();
  SurfaceProjector(const SurfaceProjector&) = delete;
  SurfaceProjector& operator=(const SurfaceProjector&) = delete;

  struct Hit {
    Vec3 point;
    Vec3 normal;  // unit normal of the triangle the closest point lies on
  };
  Hit closest(const Vec3& p) const;
  double distance(const Vec3& p) const;

private:
  struct Tree;
  std::unique_ptr<Tree> tree_;
};

// The design as `rodfab validate` reads it (the same reader on the document writeDesign writes,
// geometry::summarizeDesignDocument: each rod built and let go), so rods-from-mesh and rods-from-cad never
// write a design that validate refuses. Throws MeshError naming
// `file`, the first problem and where it is (`rodName(i)` says what rod i came from).
void requireValidDesign(const geometry::RodStructure& structure, const std::filesystem::path& file,
                        const std::function<std::string(std::size_t)>& rodName);

// Cubic B-spline interpolating `points` (at least 4, no two consecutive equal) at chord-length
// parameters normalized to [0, 1], knots by averaging (Piegl & Tiller, The NURBS Book, A9.1). The first
// and last control points are exactly the first and last data points.
geometry::NurbsCurve interpolateCubic(const std::vector<Vec3>& points);

// The smallest radius of curvature of `curve` (mm; infinity where it is straight), from its first and
// second derivatives at `pointsPerSpan` + 1 points of every knot span. Corners between spans (C0
// points, where the rod's solid has a joint) are not bends and are not seen.
double smallestBendRadius(const geometry::NurbsCurve& curve, int pointsPerSpan = 16);

}  // namespace rodfab::meshing
