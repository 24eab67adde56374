#include "slicer/mesh_rods_summary.hpp"

#include <cmath>
#include <cstdio>

namespace rodfab::cli {

nlohmann::json meshRodsJson(const MeshRodsSummary& s) {
  const meshing::MeshRodReport& r = s.report;
  const geometry::Box3 box = s.rods.bounds();
  return {{"mesh", s.mesh}, {"output", s.output},
          {"input", {{"vertices", r.inputVertices}, {"faces", r.inputFaces}, {"welded_vertices", r.weldedVertices}}},
          {"simplified", {{"vertices", r.simplifiedVertices}, {"faces", r.simplifiedFaces}, {"faces_requested", r.requestedFaces}, {"boundary_edges", r.boundaryEdges}}},
          {"nodes", r.nodes}, {"rods", r.rods}, {"components", r.components},
          {"surface", {{"tolerance_mm", s.surfaceToleranceMm}, {"largest_distance_mm", r.largestSurfaceDistance},
                       {"refined_rods", r.refinedRods}, {"rods_above_tolerance", r.rodsAboveTolerance},
                       {"rods_held_off_creases", r.rodsHeldOffCreases}}},
          // null when every rod is straight (JSON has no infinity)
          {"bends", {{"smallest_radius_mm", std::isfinite(r.smallestBendRadius) ? nlohmann::json(r.smallestBendRadius) : nlohmann::json()},
                     {"section_radius_mm", s.rods.rods.empty() ? 0.0 : s.rods.rods.front().section().boundingRadius()},
                     {"rods_tighter_than_section", r.rodsBentTighterThanSection}}},
          {"bounds_mm", {{"min", {box.min().x(), box.min().y(), box.min().z()}}, {"max", {box.max().x(), box.max().y(), box.max().z()}}}},
          {"seconds", {{"read", r.readSeconds}, {"simplify", r.simplifySeconds}, {"rods", r.rodSeconds}}}};
}

void printMeshRodsLines(const MeshRodsSummary& s) {
  const meshing::MeshRodReport& r = s.report;
  std::printf("mesh:       %s: %zu vertices, %zu triangles (%zu duplicate vertices welded), %.2f s\n", s.mesh.c_str(),
              r.inputVertices, r.inputFaces, r.weldedVertices, r.readSeconds);
  std::printf("simplified: %zu triangles, %zu boundary edges, %.2f s\n", r.simplifiedFaces, r.boundaryEdges, r.simplifySeconds);
  std::printf("rods:       %zu rods, %zu nodes, %zu connected part%s, %.2f s\n", r.rods, r.nodes, r.components,
              r.components == 1 ? "" : "s", r.rodSeconds);
  std::printf("surface:    centerlines within %.3g mm of the mesh (tolerance %.3g mm; %zu rods refined)\n",
              r.largestSurfaceDistance, s.surfaceToleranceMm, r.refinedRods);
  if (std::isfinite(r.smallestBendRadius))
    std::printf("bends:      smallest radius of curvature %.3g mm (%zu rods bend tighter than their section's radius)\n",
                r.smallestBendRadius, r.rodsBentTighterThanSection);
  std::printf("wrote:      %s\n", s.output.c_str());
}

void warnMeshRods(const MeshRodsSummary& s) {
  const meshing::MeshRodReport& r = s.report;
  if (r.simplifiedFaces > r.requestedFaces)
    std::fprintf(stderr, "warning: the mesh simplified to %zu faces, not the %zu asked for (--faces): every further edge "
                 "collapse would turn a face over (a surface folded or thinner than its triangles are wide); the rods "
                 "follow the %zu faces\n", r.simplifiedFaces, r.requestedFaces, r.simplifiedFaces);
  if (r.rodsAboveTolerance > r.rodsHeldOffCreases)
    std::fprintf(stderr, "warning: %zu rods leave the surface by up to %.3g mm, more than --surface-tolerance %g: "
                 "give more --faces or --subdivisions\n", r.rodsAboveTolerance - r.rodsHeldOffCreases, r.largestSurfaceDistance,
                 s.surfaceToleranceMm);
  if (r.rodsHeldOffCreases > 0)
    std::fprintf(stderr, "warning: %zu rods stay up to %.3g mm off the surface, more than --surface-tolerance %g, where following "
                 "it closer would bend them tighter than their section (the mesh's creases are sharper than the rods can follow): "
                 "give a smaller --diameter or a smoother mesh\n", r.rodsHeldOffCreases, r.largestSurfaceDistance, s.surfaceToleranceMm);
  if (r.rodsBentTighterThanSection > 0)
    std::fprintf(stderr, "warning: %zu of the %zu rods bend tighter than their section's radius (down to a %.3g mm radius of "
                 "curvature): the section folds over itself inside the bend; give fewer --faces or a smaller --diameter\n",
                 r.rodsBentTighterThanSection, r.rods, r.smallestBendRadius);
  if (r.components > 1)
    std::fprintf(stderr, "warning: the rods form %zu separate parts (the mesh has separate pieces)\n", r.components);
}

}  // namespace rodfab::cli
