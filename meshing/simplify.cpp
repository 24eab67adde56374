// Simplification by CGAL's edge collapse with Garland-Heckbert plane quadrics (the choice is measured
// against Lindstrom-Turk and OpenMesh's decimater in meshing/README.md).
#include "common/interrupt.hpp"
#include "meshing/mesh.hpp"

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Bounded_normal_change_placement.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_plane_policies.h>
#include <CGAL/Surface_mesh_simplification/Edge_collapse_visitor_base.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/boost/graph/Euler_operations.h>

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace rodfab::meshing {

namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;
namespace SMS = CGAL::Surface_mesh_simplification;

// Stops at the edge count, or at once when a signal arrives (the caller then throws Interrupted).
struct StopAtCountOrSignal {
  SMS::Count_stop_predicate<Mesh> count;
  template <typename Profile>
  bool operator()(const double& cost, const Profile& profile, std::size_t initialEdges, std::size_t currentEdges) const {
    return count(cost, profile, initialEdges, currentEdges) || common::interruptRequested() != 0;
  }
};

// Polls for a signal while edge_collapse collects and costs every edge, before it first asks the stop
// predicate: 0.3 s and more of a 360,000-triangle sphere, which a signal then waited out. Interrupted
// thrown here leaves edge_collapse, the half-simplified mesh discarded with it.
struct PollWhileCollecting : SMS::Edge_collapse_visitor_base<Mesh> {
  std::size_t collected = 0;
  void OnCollected(const Profile&, const boost::optional<FT>&) {
    if (++collected % 4096 == 0) common::throwIfInterrupted();
  }
};

Mesh toSurfaceMesh(const TriangleMesh& in) {
  Mesh mesh;
  mesh.reserve(in.points.size(), in.triangles.size() * 3 / 2 + 3, in.triangles.size());
  for (const Vec3& p : in.points) mesh.add_vertex(Kernel::Point_3(p.x(), p.y(), p.z()));
  for (const Triangle& t : in.triangles)
    if (mesh.add_face(Mesh::Vertex_index(t[0]), Mesh::Vertex_index(t[1]), Mesh::Vertex_index(t[2])) == Mesh::null_face())
      throw std::logic_error("simplifyMesh: the checked mesh is not manifold");
  return mesh;
}

TriangleMesh fromSurfaceMesh(Mesh& mesh) {
  mesh.collect_garbage();
  TriangleMesh out;
  out.points.reserve(mesh.number_of_vertices());
  for (Mesh::Vertex_index v : mesh.vertices()) out.points.emplace_back(mesh.point(v).x(), mesh.point(v).y(), mesh.point(v).z());
  for (Mesh::Face_index f : mesh.faces()) {
    Triangle t{};
    int k = 0;
    for (Mesh::Vertex_index v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) t[k++] = static_cast<std::uint32_t>(v.idx());
    out.triangles.push_back(t);
  }
  canonicalizeTriangles(out.triangles);
  return out;
}

using Point = Kernel::Point_3;
using Vector = Kernel::Vector_3;

// Pairs of faces within this angle of one plane may have their shared edge flipped (see flipTowardDelaunay;
// meshing/README.md, "Bends", for the measurements behind it).
constexpr double kFlipDihedralDegrees = 8.0;
constexpr int kMaxFlipPasses = 50;

// The angle at `at` of the triangle (at, p, q), radians.
double angleAt(const Point& at, const Point& p, const Point& q) {
  const Vector u = p - at, v = q - at;
  return std::atan2(std::sqrt(CGAL::cross_product(u, v).squared_length()), u * v);
}

// Whether the edge of halfedge h, between faces (a, b, c) and (b, a, d), is better flipped to (c, d):
// the two faces lie within kFlipDihedralDegrees of one plane, the angles facing the edge sum to more
// than pi (the edge is not locally Delaunay), and both faces after the flip face as both did before
// (the quadrilateral is convex). False where (c, d) is an edge already.
bool flipImproves(const Mesh& mesh, Mesh::Halfedge_index h) {
  const Mesh::Halfedge_index o = mesh.opposite(h);
  const Mesh::Vertex_index c = mesh.target(mesh.next(h)), d = mesh.target(mesh.next(o));
  if (c == d || CGAL::halfedge(c, d, mesh).second) return false;
  const Point &a = mesh.point(mesh.source(h)), &b = mesh.point(mesh.target(h)), &pc = mesh.point(c), &pd = mesh.point(d);
  const Vector n1 = CGAL::cross_product(b - a, pc - a), n2 = CGAL::cross_product(a - b, pd - b);
  const double cosLimit = std::cos(kFlipDihedralDegrees * std::numbers::pi / 180.0);
  if (n1 * n2 < cosLimit * std::sqrt(n1.squared_length() * n2.squared_length())) return false;
  if (angleAt(pc, a, b) + angleAt(pd, b, a) <= std::numbers::pi + 1e-9) return false;
  const Vector m1 = CGAL::cross_product(a - pc, pd - pc), m2 = CGAL::cross_product(b - pd, pc - pd);
  return m1 * n1 > 0 && m2 * n1 > 0 && m1 * n2 > 0 && m2 * n2 > 0;
}

// Flips edges toward a Delaunay triangulation where their faces are nearly coplanar, in passes over
// the edges in index order until none flips (kMaxFlipPasses at most): the same mesh gives the same
// result. Where every collapse costs nothing (a flat or gently curved region: the plane quadrics see
// no error) the simplifier leaves thin triangles, whose dual has rods turning sharply between close
// centroids (meshing/README.md, "Bends": a flat plate at --faces 1000 had 77 rods tighter than a 1 mm
// section, none after). Vertices stay; faces, edges and the count of each stay.
void flipTowardDelaunay(Mesh& mesh) {
  for (int pass = 0; pass < kMaxFlipPasses; ++pass) {
    common::throwIfInterrupted();
    bool flipped = false;
    for (Mesh::Edge_index e : mesh.edges()) {
      if (mesh.is_border(e) || !flipImproves(mesh, mesh.halfedge(e))) continue;
      CGAL::Euler::flip_edge(mesh.halfedge(e), mesh);
      flipped = true;
    }
    if (!flipped) return;
  }
}

}  // namespace

TriangleMesh simplifyMesh(const TriangleMesh& input, std::size_t targetFaces) {
  Mesh mesh = toSurfaceMesh(input);
  // The collapse counts edges and stops below the threshold: a closed triangle mesh has 3F/2 edges,
  // and each collapse removes 3 edges and 2 faces, so this stops at F = targetFaces (or one less when
  // odd; an open mesh stops a little below, its boundary edges counting too).
  StopAtCountOrSignal stop{SMS::Count_stop_predicate<Mesh>(targetFaces * 3 / 2 + 1)};
  using Policies = SMS::GarlandHeckbert_plane_policies<Mesh, Kernel>;
  Policies policies(mesh);
  // Refuse collapses that would flip a face's normal: the dual's nodes then stay in order on the surface.
  SMS::Bounded_normal_change_placement<Policies::Get_placement> placement(policies.get_placement());
  SMS::edge_collapse(mesh, stop,
                     CGAL::parameters::get_cost(policies.get_cost()).get_placement(placement).visitor(PollWhileCollecting()));
  common::throwIfInterrupted();
  mesh.collect_garbage();  // the collapsed edges gone, so the flips' passes visit live ones only
  flipTowardDelaunay(mesh);
  return fromSurfaceMesh(mesh);
}

}  // namespace rodfab::meshing
