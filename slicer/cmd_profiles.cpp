#include "printer_profiles/printer_profiles.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>

namespace rodfab::cli {

namespace pp = printer_profiles;

namespace {

nlohmann::json profileJson(const pp::Profile& p) {
  nlohmann::json materials = nlohmann::json::array();
  for (const auto& m : p.materials) {
    materials.push_back({{"name", m.name}, {"role", pp::toString(m.role)}, {"density_g_per_ml", m.densityGPerMl}});
    if (p.jobFormat == pp::JobFormat::Gcvf && m.role != pp::MaterialRole::Support) materials.back()["rgba"] = m.rgba;
  }
  nlohmann::json modes = nlohmann::json::array();
  for (const pp::PrintMode& mode : p.printModes) modes.push_back({{"name", mode.name}, {"layer_thickness_mm", mode.layerThicknessMm}});
  return {{"name", p.name},
                  {"printer", p.printer},
                  {"file", p.source.string()},
                  {"dpi", {p.xDpi, p.yDpi}},
                  {"voxel_size_mm", p.voxelSizeMm},
                  {"tray_mm", p.trayMm},
                  {"model_material_slots", p.modelMaterialSlots},
                  {"materials", materials},
                  {"output_format", pp::toString(p.jobFormat)},
                  {"print_modes", modes},
                  {"image_format", pp::toString(p.imageFormat)},
                  {"bit_depth", p.imageBitDepth()},
                  {"column_alignment", p.columnAlignment},
                  {"support_policy", pp::toString(p.supportPolicy)}};
}

void printProfile(const pp::Profile& p) {
  std::printf("profile:       %s (%s)\n", p.name.c_str(), p.source.c_str());
  std::printf("printer:       %s\n", p.printer.c_str());
  std::printf("resolution:    x %d dpi (image columns), y %d dpi (image rows), %.3f mm layers\n", p.xDpi, p.yDpi,
              p.voxelSizeMm[2]);
  std::printf("voxel:         %.4f x %.4f x %.4f mm\n", p.voxelSizeMm[0], p.voxelSizeMm[1], p.voxelSizeMm[2]);
  std::printf("tray:          %.0f x %.0f x %.0f mm\n", p.trayMm[0], p.trayMm[1], p.trayMm[2]);
  std::printf("model slots:   %d\n", p.modelMaterialSlots);
  for (const pp::PrintMode& mode : p.printModes)
    std::printf("print mode:    %-16s %.3f mm layers%s\n", mode.name.c_str(), mode.layerThicknessMm,
                mode.name == p.printModes.front().name ? " (default)" : "");
  for (const auto& m : p.materials) {
    std::printf("material:      %-16s %-8s %.3f g/mL", m.name.c_str(), pp::toString(m.role), m.densityGPerMl);
    if (p.jobFormat == pp::JobFormat::Gcvf && m.role != pp::MaterialRole::Support)
      std::printf("  RGBA %d %d %d %d", m.rgba[0], m.rgba[1], m.rgba[2], m.rgba[3]);
    std::printf("\n");
  }
  std::printf("job format:    %s\n", p.jobFormat == pp::JobFormat::Gcvf
                                        ? "GrabCAD Voxel Print (.gcvf: one RGBA PNG per layer, each colour a material, ConfigFile.xml)"
                                        : "bitmap stacks (one 1-bit image per material per layer) and a build file");
  std::printf("images:        %d-bit %s, width a multiple of %d, padding %d columns / %d rows, origin top-left\n",
              p.imageBitDepth(), pp::toString(p.imageFormat), p.columnAlignment, p.paddingVoxels[0], p.paddingVoxels[1]);
  std::printf("row order:     %s\n", p.rowOrder.c_str());
  std::printf("build file:    %s (format version %d)\n", p.buildFileName.c_str(), p.buildFormatVersion);
  std::printf("support:       %s\n", pp::toString(p.supportPolicy));
}

}  // namespace

int runProfiles(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("profile", po::value<std::string>()->value_name("PROFILE"), "show one profile in full (a bundled name or a profile file)")
      ("json", "print as JSON on stdout");
  po::variables_map vm;
  if (auto code = parseOptionsWithInput("profiles", options, "profile", args, vm)) return *code;
  commandLineAccepted();

  std::vector<pp::Profile> profiles;
  try {
    if (vm.count("profile")) {
      profiles.push_back(pp::loadProfile(vm["profile"].as<std::string>()));
    } else {
      for (const std::string& name : pp::bundledProfileNames()) profiles.push_back(pp::loadProfile(name));
    }
  } catch (const pp::ProfileError& e) {
    std::cerr << e.what() << '\n';
    return kFailed;
  }
  if (vm.count("json")) {
    nlohmann::json list = nlohmann::json::array();
    for (const pp::Profile& p : profiles) list.push_back(profileJson(p));
    std::cout << list.dump(2) << '\n';
    return kOk;
  }
  if (!vm.count("profile")) {
    std::printf("bundled profiles (%s):\n", pp::bundledProfileDir().c_str());
    for (const pp::Profile& p : profiles)
      std::printf("  %-32s %s, %d x %d dpi, %.3f mm layers, tray %.0f x %.0f x %.0f mm\n", p.name.c_str(), p.printer.c_str(),
                  p.xDpi, p.yDpi, p.voxelSizeMm[2], p.trayMm[0], p.trayMm[1], p.trayMm[2]);
    return kOk;
  }
  printProfile(profiles.front());
  return kOk;
}

}  // namespace rodfab::cli
