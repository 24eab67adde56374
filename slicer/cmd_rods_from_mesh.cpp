// rodfab rods-from-mesh: a triangle mesh becomes a rod structure (the dual of its simplified version,
// laid on the original surface), written as a design file.
#include "geometry/geometry.hpp"
#include "meshing/meshing.hpp"
#include "printer_profiles/profile.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <variant>

namespace rodfab::cli {

namespace {

struct MeshSettings {
  std::string mesh, output, profile;
  meshing::MeshRodOptions options;
  bool force = false, json = false;
};

void addMeshOptions(po::options_description& options) {
  options.add_options()
      ("mesh", po::value<std::string>()->required(), "triangle mesh: .stl (binary or ASCII), .obj, .ply or .off, in mm")
      ("faces", po::value<int>()->default_value(200), "triangles of the simplified mesh: about this many rod nodes, 1.5 times as many rods")
      ("diameter", po::value<double>()->required(), "rod diameter (mm); for ellipses and rectangles the thickness normal to the surface")
      ("output,o", po::value<std::string>()->required(), "design file to write (rodfab.design/1)")
      ("section", po::value<std::string>()->default_value("circle"), "circle | ellipse | rectangle")
      ("breadth", po::value<double>(), "ellipse or rectangle: the size within the surface (mm; default: --diameter)")
      ("modulus", po::value<double>()->default_value(120.0), "Young's modulus of every rod (MPa)")
      ("subdivisions", po::value<int>()->default_value(4), "points per rod projected onto the surface and interpolated")
      ("surface-tolerance", po::value<double>()->default_value(0.05), "largest distance of a centerline from the surface (mm)")
      ("caps", po::value<std::string>()->default_value("round"), "rod ends: round | flat")
      ("profile", po::value<std::string>()->default_value("stratasys-objet500-connex3"), "printer profile whose tray the result is checked against")
      ("force", "replace an existing design file at --output")
      ("json", "print the summary as JSON on stdout");
}

std::optional<geometry::Section> parseSection(const po::variables_map& vm, double diameter) {
  const std::string shape = vm["section"].as<std::string>();
  if (shape == "circle") {
    if (vm.count("breadth")) return usageError("rods-from-mesh", "--breadth goes with --section ellipse or rectangle"), std::nullopt;
    return geometry::Section::circle(diameter);
  }
  double breadth = diameter;
  if (vm.count("breadth")) {
    const std::optional<double> b = realOption("rods-from-mesh", vm, "breadth", 1e-3, 1000, "mm");
    if (!b) return std::nullopt;
    breadth = *b;
  }
  if (shape == "ellipse") return geometry::Section::ellipse(diameter, breadth);
  if (shape == "rectangle") return geometry::Section::rectangle(diameter, breadth);
  usageError("rods-from-mesh", "--section: expected circle, ellipse or rectangle, got '" + shape + "'");
  return std::nullopt;
}

std::variant<MeshSettings, int> parseMesh(const std::vector<std::string>& args) {
  po::options_description options("options");
  addMeshOptions(options);
  po::positional_options_description positional;
  positional.add("mesh", 1);
  po::variables_map vm;
  const char* synopsis = "MESH --faces N --diameter D --output DESIGN.json [--section circle|ellipse|rectangle] "
                         "[--breadth B] [--modulus E] [--subdivisions K] [--surface-tolerance T] [--force] [--json]";
  if (auto code = parseOptions("rods-from-mesh", synopsis, options, positional, args, vm)) return *code;
  MeshSettings s;
  s.mesh = vm["mesh"].as<std::string>(), s.output = vm["output"].as<std::string>();
  s.profile = vm["profile"].as<std::string>();
  s.force = vm.count("force") > 0, s.json = vm.count("json") > 0;
  meshing::MeshRodOptions& o = s.options;
  const auto faces = intOption("rods-from-mesh", vm, "faces", meshing::kMinFaces, meshing::kMaxFaces);
  const auto subdivisions = intOption("rods-from-mesh", vm, "subdivisions", meshing::kMinSubdivisions, meshing::kMaxSubdivisions);
  const auto diameter = realOption("rods-from-mesh", vm, "diameter", 1e-3, 1000, "mm");
  const auto modulus = realOption("rods-from-mesh", vm, "modulus", 1e-3, geometry::kMaxModulusMpa, "MPa");
  const auto tolerance = realOption("rods-from-mesh", vm, "surface-tolerance", 1e-6, 1000, "mm");
  if (!faces || !subdivisions || !diameter || !modulus || !tolerance) return kUsage;
  const std::optional<geometry::Section> section = parseSection(vm, *diameter);
  if (!section) return kUsage;
  const std::string caps = vm["caps"].as<std::string>();
  if (caps != "round" && caps != "flat") return usageError("rods-from-mesh", "--caps: expected round or flat, got '" + caps + "'");
  o.faces = *faces, o.subdivisions = *subdivisions, o.modulusMpa = *modulus, o.surfaceTolerance = *tolerance;
  o.section = *section;
  o.caps = caps == "round" ? geometry::CapStyle::Round : geometry::CapStyle::Flat;
  return s;
}

// A warning on stderr for every axis where the rods' bounding box is larger than the tray.
void warnOverhang(const geometry::RodStructure& rods, const printer_profiles::Profile& profile) {
  const geometry::Vec3 size = rods.bounds().sizes();
  const char* axis = "xyz";
  for (int a = 0; a < 3; ++a)
    if (size[a] > profile.trayMm[a])
      std::fprintf(stderr, "warning: the rods are %.1f mm long in %c, %.1f mm more than the tray of %s (%.1f mm): scale the mesh\n",
                   size[a], axis[a], size[a] - profile.trayMm[a], profile.name.c_str(), profile.trayMm[a]);
}

nlohmann::json summaryJson(const MeshSettings& s, const meshing::MeshRodReport& r, const geometry::RodStructure& rods) {
  const geometry::Box3 box = rods.bounds();
  return {{"mesh", s.mesh}, {"output", s.output},
          {"input", {{"vertices", r.inputVertices}, {"faces", r.inputFaces}, {"welded_vertices", r.weldedVertices}}},
          {"simplified", {{"vertices", r.simplifiedVertices}, {"faces", r.simplifiedFaces}, {"boundary_edges", r.boundaryEdges}}},
          {"nodes", r.nodes}, {"rods", r.rods}, {"components", r.components},
          {"surface", {{"tolerance_mm", s.options.surfaceTolerance}, {"largest_distance_mm", r.largestSurfaceDistance},
                       {"refined_rods", r.refinedRods}, {"rods_above_tolerance", r.rodsAboveTolerance}}},
          {"bounds_mm", {{"min", {box.min().x(), box.min().y(), box.min().z()}}, {"max", {box.max().x(), box.max().y(), box.max().z()}}}},
          {"seconds", {{"read", r.readSeconds}, {"simplify", r.simplifySeconds}, {"rods", r.rodSeconds}}}};
}

void printSummary(const MeshSettings& s, const meshing::MeshRodReport& r) {
  std::printf("mesh:       %s: %zu vertices, %zu triangles (%zu duplicate vertices welded), %.2f s\n", s.mesh.c_str(),
              r.inputVertices, r.inputFaces, r.weldedVertices, r.readSeconds);
  std::printf("simplified: %zu triangles, %zu boundary edges, %.2f s\n", r.simplifiedFaces, r.boundaryEdges, r.simplifySeconds);
  std::printf("rods:       %zu rods, %zu nodes, %zu connected part%s, %.2f s\n", r.rods, r.nodes, r.components,
              r.components == 1 ? "" : "s", r.rodSeconds);
  std::printf("surface:    centerlines within %.3g mm of the mesh (tolerance %.3g mm; %zu rods refined)\n",
              r.largestSurfaceDistance, s.options.surfaceTolerance, r.refinedRods);
  std::printf("wrote:      %s\n", s.output.c_str());
}

void printWarnings(const MeshSettings& s, const meshing::MeshRodReport& r) {
  if (r.rodsAboveTolerance > 0)
    std::fprintf(stderr, "warning: %zu rods leave the surface by up to %.3g mm, more than --surface-tolerance %g: "
                 "give more --faces or --subdivisions\n", r.rodsAboveTolerance, r.largestSurfaceDistance, s.options.surfaceTolerance);
  if (r.components > 1)
    std::fprintf(stderr, "warning: the rods form %zu separate parts (the mesh has separate pieces)\n", r.components);
}

}  // namespace

int runRodsFromMesh(const std::vector<std::string>& args) {
  auto parsed = parseMesh(args);
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const MeshSettings& s = std::get<MeshSettings>(parsed);
  commandLineAccepted();
  if (!outputAllowed(s.output, {s.mesh}, {"design file", s.force, "--force", geometry::isDesignFile})) return kFailed;
  printer_profiles::Profile profile;
  try {
    profile = printer_profiles::loadProfile(s.profile);
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\nrodfab rods-from-mesh: nothing was written\n";
    return kFailed;
  }
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
  printWarnings(s, result.report);
  warnOverhang(result.structure, profile);
  if (s.json) std::cout << summaryJson(s, result.report, result.structure).dump(2) << '\n';
  else printSummary(s, result.report);
  return kOk;
}

}  // namespace rodfab::cli
