// rodfab rods-from-cad: every edge curve of a STEP or IGES model becomes a rod with its exact NURBS.
#include "geometry/geometry.hpp"
#include "meshing/meshing.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"
#include "slicer/shape_options.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>

namespace rodfab::cli {

int runRodsFromCad(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("model", po::value<std::string>()->required()->value_name("FILE.step|.stp|.iges|.igs"), "CAD model: .step/.stp or .iges/.igs (lengths in mm)")
      ("diameter", po::value<double>()->required()->value_name("D"), "rod diameter (mm); for ellipses and rectangles the size along the frame's d1")
      ("output,o", po::value<std::string>()->required()->value_name("DESIGN.json"), "design file to write (rodfab.design/1)")
      ("joint-tolerance", po::value<double>()->default_value(1e-3)->value_name("T"), "curve ends closer than this (mm) become one joint")
      ("force", "replace an existing design file at --output")
      ("json", "print the summary as JSON on stdout");
  addRodShapeOptions(options);
  po::variables_map vm;
  if (auto code = parseOptionsWithInput("rods-from-cad", options, "model", args, vm)) return *code;
  const std::string model = vm["model"].as<std::string>(), output = vm["output"].as<std::string>();
  const auto tolerance = realOption("rods-from-cad", vm, "joint-tolerance", 1e-9, 100, "mm");
  const std::optional<RodShape> shape = parseRodShape("rods-from-cad", vm);
  if (!tolerance || !shape) return kUsage;
  commandLineAccepted();
  std::string profileName;
  std::array<double, 3> trayMm{};
  if (!loadTrayProfile("rods-from-cad", vm["profile"].as<std::string>(), trayMm, profileName)) return kFailed;
  if (!outputAllowed(output, {model}, {"design file", vm.count("force") > 0, "--force", geometry::isDesignRodfabWrote})) return kFailed;
  meshing::CadRodOptions o;
  o.section = shape->section, o.caps = shape->caps, o.modulusMpa = shape->modulusMpa, o.jointTolerance = *tolerance;
  meshing::CadDesignWritten result;
  try {
    result = meshing::writeDesignFromCad(model, o, output, "rods from " + model + " by rodfab rods-from-cad");
  } catch (const meshing::MeshError& e) {
    std::cerr << e.what() << "\n" << model << ": nothing was written\n";
    return kFailed;
  }
  warnTrayOverhang(result.summary.bounds, trayMm, profileName);
  warnThickRods(result.summary, o.section);
  const meshing::CadRodReport& r = result.report;
  if (r.untranslated > 0)
    std::fprintf(stderr, "warning: OpenCASCADE could not convert %zu %s of the model, wholly or in part, and the design lacks "
                 "what it could not: %s%s; check the model in the program that wrote it\n", r.untranslated,
                 r.untranslated == 1 ? "entity" : "entities", r.firstUntranslated.c_str(), r.untranslated > 1 ? " (the first)" : "");
  if (r.rodsBentTighterThanSection > 0)
    std::fprintf(stderr, "warning: %zu of the %zu rods bend tighter than their section's radius (down to a %.3g mm radius of "
                 "curvature): the section folds over itself inside the bend; give a smaller --diameter or gentler curves\n",
                 r.rodsBentTighterThanSection, r.rods, r.smallestBendRadius);
  if (vm.count("json")) {
    std::cout << nlohmann::json{{"model", model}, {"output", output}, {"edges", r.edges}, {"rods", r.rods}, {"joints", r.joints},
                                {"skipped_degenerate", r.skippedDegenerate}, {"largest_end_move_mm", r.largestEndMove},
                                {"approximated", r.approximated}, {"largest_approximation_error_mm", r.largestApproximationError},
                                {"untranslated", r.untranslated}, {"first_untranslated", r.firstUntranslated},
                                // null when every rod is straight (JSON has no infinity)
                                {"bends", {{"smallest_radius_mm", std::isfinite(r.smallestBendRadius) ? nlohmann::json(r.smallestBendRadius) : nlohmann::json()},
                                           {"section_radius_mm", o.section.boundingRadius()},
                                           {"rods_tighter_than_section", r.rodsBentTighterThanSection}}}}
                     .dump(2)
              << '\n';
    return kOk;
  }
  std::printf("model:      %s: %zu edges (%zu without a curve skipped)\n", model.c_str(), r.edges, r.skippedDegenerate);
  std::printf("rods:       %zu rods, %zu joints (ends merged within %g mm, moved by at most %.3g mm)\n", r.rods, r.joints,
              *tolerance, r.largestEndMove);
  if (r.approximated > 0)
    std::printf("curves:     %zu of a degree above %d approximated by degree %d within %.2g mm (the farthest %.2g mm)\n",
                r.approximated, geometry::kMaxDegree, geometry::kMaxDegree, meshing::kCadApproximationToleranceMm,
                r.largestApproximationError);
  if (std::isfinite(r.smallestBendRadius))
    std::printf("bends:      smallest radius of curvature %.3g mm (%zu rods bend tighter than their section's radius)\n",
                r.smallestBendRadius, r.rodsBentTighterThanSection);
  std::printf("wrote:      %s\n", output.c_str());
  return kOk;
}

}  // namespace rodfab::cli
