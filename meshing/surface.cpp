// Closest points on the original surface: a CGAL AABB tree over its triangles.
#include "meshing/mesh.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

namespace rodfab::meshing {

namespace {
using Kernel = CGAL::Simple_cartesian<double>;
using Triangle3 = Kernel::Triangle_3;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, std::vector<Triangle3>::const_iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
Kernel::Point_3 toPoint(const Vec3& p) { return {p.x(), p.y(), p.z()}; }
Vec3 toVec(const Kernel::Point_3& p) { return {p.x(), p.y(), p.z()}; }
}  // namespace

struct SurfaceProjector::Tree {
  std::vector<Triangle3> triangles;
  meshing::Tree tree;
};

SurfaceProjector::SurfaceProjector(const TriangleMesh& mesh) : tree_(std::make_unique<Tree>()) {
  tree_->triangles.reserve(mesh.triangles.size());
  for (const Triangle& t : mesh.triangles)
    tree_->triangles.emplace_back(toPoint(mesh.points[t[0]]), toPoint(mesh.points[t[1]]), toPoint(mesh.points[t[2]]));
  tree_->tree.insert(tree_->triangles.cbegin(), tree_->triangles.cend());
  tree_->tree.accelerate_distance_queries();
  tree_->tree.build();
  // One query here builds the search structures, so queries from several threads only read the tree.
  if (!mesh.points.empty()) tree_->tree.closest_point(toPoint(mesh.points.front()));
}

SurfaceProjector::~SurfaceProjector() = default;

SurfaceProjector::Hit SurfaceProjector::closest(const Vec3& p) const {
  const auto [point, id] = tree_->tree.closest_point_and_primitive(toPoint(p));
  const Triangle3& t = *id;
  const Vec3 normal = (toVec(t[1]) - toVec(t[0])).cross(toVec(t[2]) - toVec(t[0])).normalized();
  return {toVec(point), normal};
}

double SurfaceProjector::distance(const Vec3& p) const {
  return std::sqrt(tree_->tree.squared_distance(toPoint(p)));
}

}  // namespace rodfab::meshing
