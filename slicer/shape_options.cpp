#include "slicer/shape_options.hpp"

#include "geometry/design_file.hpp"
#include "printer_profiles/profile.hpp"
#include "slicer/profile_option.hpp"

#include <algorithm>
#include <cstdio>
#include <iostream>

namespace rodfab::cli {

void addRodShapeOptions(po::options_description& options) {
  options.add_options()
      ("section", po::value<std::string>()->default_value("circle")->value_name("circle|ellipse|rectangle"), "circle | ellipse | rectangle")
      ("breadth", po::value<double>()->value_name("B"), "ellipse or rectangle: the size along the frame's d2 (mm; default: --diameter)")
      ("modulus", po::value<double>()->default_value(120.0)->value_name("E"), "Young's modulus of every rod (MPa)")
      ("caps", po::value<std::string>()->default_value("round")->value_name("round|flat"), "rod ends: round | flat")
      ("profile", po::value<std::string>()->default_value(kDefaultProfileName)->value_name("NAME|FILE"),
       "printer profile whose tray the result is checked against (a warning when it does not fit)");
}

std::optional<RodShape> parseRodShape(const std::string& command, const po::variables_map& vm) {
  const auto diameter = realOption(command, vm, "diameter", 1e-3, 1000, "mm");
  const auto modulus = realOption(command, vm, "modulus", 1e-3, geometry::kMaxModulusMpa, "MPa");
  if (!diameter || !modulus) return std::nullopt;
  RodShape shape;
  shape.modulusMpa = *modulus;
  const std::string caps = vm["caps"].as<std::string>();
  if (caps != "round" && caps != "flat") return usageError(command, "--caps: expected round or flat, got '" + caps + "'"), std::nullopt;
  shape.caps = caps == "round" ? geometry::CapStyle::Round : geometry::CapStyle::Flat;
  const std::string section = vm["section"].as<std::string>();
  if (section == "circle") {
    if (vm.count("breadth")) return usageError(command, "--breadth goes with --section ellipse or rectangle"), std::nullopt;
    shape.section = geometry::Section::circle(*diameter);
    return shape;
  }
  double breadth = *diameter;
  if (vm.count("breadth")) {
    const auto b = realOption(command, vm, "breadth", 1e-3, 1000, "mm");
    if (!b) return std::nullopt;
    breadth = *b;
  }
  if (section == "ellipse") shape.section = geometry::Section::ellipse(*diameter, breadth);
  else if (section == "rectangle") shape.section = geometry::Section::rectangle(*diameter, breadth);
  else return usageError(command, "--section: expected circle, ellipse or rectangle, got '" + section + "'"), std::nullopt;
  return shape;
}

bool loadTrayProfile(const std::string& command, const std::string& nameOrPath, std::array<double, 3>& trayMm, std::string& name) {
  try {
    const printer_profiles::Profile profile = printer_profiles::loadProfile(nameOrPath);
    trayMm = profile.trayMm, name = profile.name;
    return true;
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\nrodfab " << command << ": nothing was written\n";
    return false;
  }
}

void warnTrayOverhang(const geometry::Box3& rodBounds, const std::array<double, 3>& trayMm, const std::string& profile) {
  const geometry::Vec3 size = rodBounds.sizes();
  const char* axis = "xyz";
  for (int a = 0; a < 3; ++a)
    if (size[a] > trayMm[a])
      std::fprintf(stderr, "warning: the rods are %.1f mm long in %c, %.1f mm more than the tray of %s (%.1f mm): scale the model\n",
                   size[a], axis[a], size[a] - trayMm[a], profile.c_str(), trayMm[a]);
}

void warnThickRods(const geometry::DesignSummary& rods, const geometry::Section& section) {
  if (rods.rodCount == 0) return;
  const double meanLength = rods.totalLength / static_cast<double>(rods.rodCount);
  const double width = std::max(section.width, section.height);
  if (!(meanLength < width)) return;
  const geometry::Vec3 size = rods.bounds.sizes();
  std::fprintf(stderr, "warning: the rods are %g mm thick but only %.3g mm long on average: they overlap each other along most "
               "of their length, print as a lump and slice slowly; the model is %.3g x %.3g x %.3g mm (drawn in other units?): "
               "scale it or give a smaller --diameter\n", width, meanLength, size.x(), size.y(), size.z());
}

}  // namespace rodfab::cli
