#include "slicer/mesh_rods_summary.hpp"

#include <cstdio>

namespace rodfab::cli {

nlohmann::json meshRodsJson(const MeshRodsSummary& s) {
  const meshing::MeshRodReport& r = s.report;
  const geometry::Box3 box = s.rods.bounds();
  return {{"mesh", s.mesh}, {"output", s.output},
          {"input", {{"vertices", r.inputVertices}, {"faces", r.inputFaces}, {"welded_vertices", r.weldedVertices}}},
          {"simplified", {{"vertices", r.simplifiedVertices}, {"faces", r.simplifiedFaces}, {"boundary_edges", r.boundaryEdges}}},
          {"nodes", r.nodes}, {"rods", r.rods}, {"components", r.components},
          {"surface", {{"tolerance_mm", s.surfaceToleranceMm}, {"largest_distance_mm", r.largestSurfaceDistance},
                       {"refined_rods", r.refinedRods}, {"rods_above_tolerance", r.rodsAboveTolerance}}},
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
  std::printf("wrote:      %s\n", s.output.c_str());
}

void warnMeshRods(const MeshRodsSummary& s) {
  const meshing::MeshRodReport& r = s.report;
  if (r.rodsAboveTolerance > 0)
    std::fprintf(stderr, "warning: %zu rods leave the surface by up to %.3g mm, more than --surface-tolerance %g: "
                 "give more --faces or --subdivisions\n", r.rodsAboveTolerance, r.largestSurfaceDistance, s.surfaceToleranceMm);
  if (r.components > 1)
    std::fprintf(stderr, "warning: the rods form %zu separate parts (the mesh has separate pieces)\n", r.components);
}

}  // namespace rodfab::cli
