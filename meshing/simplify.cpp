// Simplification by CGAL's edge collapse with Garland-Heckbert plane quadrics (the choice is measured
// against Lindstrom-Turk and OpenMesh's decimater in meshing/README.md).
#include "common/interrupt.hpp"
#include "meshing/mesh.hpp"

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Bounded_normal_change_placement.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_plane_policies.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>

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
  SMS::edge_collapse(mesh, stop, CGAL::parameters::get_cost(policies.get_cost()).get_placement(placement));
  common::throwIfInterrupted();
  return fromSurfaceMesh(mesh);
}

}  // namespace rodfab::meshing
