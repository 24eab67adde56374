// rodfab rods-from-mesh: a triangle mesh becomes a rod structure (the dual of its simplified version,
// laid on the original surface), written as a design file (slicer/mesh_rods_summary.hpp reports it).
#include "geometry/geometry.hpp"
#include "meshing/meshing.hpp"
#include "slicer/command.hpp"
#include "slicer/mesh_rods_summary.hpp"
#include "slicer/options.hpp"
#include "slicer/shape_options.hpp"

#include <iostream>
#include <variant>

namespace rodfab::cli {

namespace {

struct MeshSettings {
  std::string mesh, output, profile;
  meshing::MeshRodOptions options;
  bool force = false, json = false;
  int threads = 0;  // --threads (0: all cores)
};

void addMeshOptions(po::options_description& options) {
  options.add_options()
      ("mesh", po::value<std::string>()->required()->value_name("MESH.stl|.obj|.ply|.off"), "triangle mesh: .stl (binary or ASCII), .obj, .ply or .off, in mm")
      ("faces", po::value<int>()->default_value(200)->value_name("N"), "triangles of the simplified mesh: about this many rod nodes, 1.5 times as many rods")
      ("diameter", po::value<double>()->required()->value_name("D"), "rod diameter (mm); for ellipses and rectangles the thickness normal to the surface")
      ("output,o", po::value<std::string>()->required()->value_name("DESIGN.json"), "design file to write (rodfab.design/1)")
      ("subdivisions", po::value<int>()->default_value(4)->value_name("K"), "points per rod projected onto the surface and interpolated")
      ("surface-tolerance", po::value<double>()->default_value(0.05, "0.05")->value_name("T"), "largest distance of a centerline from the surface (mm)")
      ("force", "replace an existing design file at --output")
      ("json", "print the summary as JSON on stdout");
  addThreadsOption(options, "they build the rods; the result does not depend on their number");
  // The frame's d1 is the surface normal: --diameter is the thickness normal to the surface, --breadth
  // the size within it.
  addRodShapeOptions(options);
}

Parsed<MeshSettings> parseMesh(const std::vector<std::string>& args) {
  po::variables_map vm;
  if (auto code = parseOptionsWithInput("rods-from-mesh", addMeshOptions, "mesh", args, vm)) return *code;
  MeshSettings s;
  s.mesh = vm["mesh"].as<std::string>(), s.output = vm["output"].as<std::string>();
  s.force = vm.count("force") > 0, s.json = vm.count("json") > 0;
  meshing::MeshRodOptions& o = s.options;
  const auto faces = intOption("rods-from-mesh", vm, "faces", meshing::kMinFaces, meshing::kMaxFaces);
  const auto subdivisions = intOption("rods-from-mesh", vm, "subdivisions", meshing::kMinSubdivisions, meshing::kMaxSubdivisions);
  const auto tolerance = realOption("rods-from-mesh", vm, "surface-tolerance", 1e-6, 1000, "mm");
  const std::optional<int> threads = threadCount("rods-from-mesh", vm);
  if (!faces || !subdivisions || !tolerance || !threads) return kUsage;
  s.threads = *threads;
  const std::optional<RodShape> shape = parseRodShape("rods-from-mesh", vm);
  if (!shape) return kUsage;
  o.faces = *faces, o.subdivisions = *subdivisions, o.surfaceTolerance = *tolerance;
  o.section = shape->section, o.caps = shape->caps, o.modulusMpa = shape->modulusMpa;
  s.profile = vm["profile"].as<std::string>();
  return s;
}

// The rods made from the mesh, written and reported; the exit code.
int meshToRods(const MeshSettings& s) {
  std::string profileName;
  std::array<double, 3> trayMm{};
  if (!loadTrayProfile("rods-from-mesh", s.profile, trayMm, profileName)) return kFailed;
  if (!outputAllowed(s.output, {s.mesh}, {"design file", s.force, "--force", geometry::isDesignRodfabWrote})) return kFailed;
  meshing::MeshRods result;
  try {
    result = meshing::rodsFromMesh(s.mesh, s.options);
  } catch (const meshing::MeshError& e) {
    std::cerr << e.what() << "\n" << s.mesh << ": nothing was written\n";
    return kFailed;
  }
  const std::string description = "rods from " + s.mesh + " by rodfab rods-from-mesh (" +
                                  std::to_string(result.report.simplifiedFaces) + " faces)";
  geometry::writeDesign(result.structure, s.output, description);
  const MeshRodsSummary summary{s.mesh, s.output, s.options.surfaceTolerance, result.report, result.structure};
  warnMeshRods(summary);
  warnTrayOverhang(result.structure.bounds(), trayMm, profileName);
  warnThickRods(geometry::summarize(result.structure), s.options.section);
  if (s.json) std::cout << meshRodsJson(summary).dump(2) << '\n';
  else printMeshRodsLines(summary);
  return kOk;
}

}  // namespace

int runRodsFromMesh(const std::vector<std::string>& args) { return runAccepted(parseMesh(args), meshToRods); }

}  // namespace rodfab::cli
