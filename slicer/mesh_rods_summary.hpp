// What rodfab rods-from-mesh reports: the summary of the mesh, its simplification and the rods (text
// lines or JSON) on stdout, and warnings on stderr for rods that leave the surface or parts that do
// not touch.
#pragma once

#include "geometry/rod.hpp"
#include "meshing/meshing.hpp"

#include <nlohmann/json.hpp>

#include <string>

namespace rodfab::cli {

// The rods made from a mesh, as the summary reports them.
struct MeshRodsSummary {
  const std::string& mesh;    // the mesh file, as given
  const std::string& output;  // the design file written
  double surfaceToleranceMm;  // --surface-tolerance
  const meshing::MeshRodReport& report;
  const geometry::RodStructure& rods;
};

// input, simplified, nodes, rods, components, surface, bends, bounds_mm and seconds.
nlohmann::json meshRodsJson(const MeshRodsSummary& summary);

// The summary lines on stdout.
void printMeshRodsLines(const MeshRodsSummary& summary);

// Warns on stderr of rods farther from the surface than the tolerance and of separate parts.
void warnMeshRods(const MeshRodsSummary& summary);

}  // namespace rodfab::cli
