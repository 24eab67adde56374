#include "common/located_issues.hpp"
#include "geometry/geometry.hpp"
#include "mechanics/mechanics.hpp"
#include "mechanics/mechanics_file.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>

namespace rodfab::cli {

namespace {

std::string formatPoint(const geometry::Vec3& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.3f, %.3f, %.3f)", p.x(), p.y(), p.z());
  return buf;
}

}  // namespace

int runValidate(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("design", po::value<std::string>()->required()->value_name("DESIGN.json"), "design file (rodfab.design/1 JSON)")
      ("json", "print the summary as JSON on stdout");
  po::variables_map vm;
  if (auto code = parseOptionsWithInput("validate", options, "design", args, vm)) return *code;

  commandLineAccepted();
  const std::string file = vm["design"].as<std::string>();
  geometry::DesignSummary s;
  try {
    s = mechanics::checkDesign(file);
  } catch (const geometry::DesignError& e) {
    std::cerr << e.what() << '\n'
              << file << ": " << common::issueCountText(e.issues())
              << "; the design is not valid\n";
    return kFailed;
  } catch (const mechanics::MechanicsError& e) {
    std::cerr << e.what() << '\n' << file << ": its \"mechanics\" block cannot be solved (simulate, or optimize for a load case); the design is not valid\n";
    return kFailed;
  }
  if (vm.count("json")) {
    nlohmann::json j{{"design", file},
                     {"valid", true},
                     {"rods", s.rodCount},
                     {"total_length_mm", s.totalLength},
                     {"bounds_mm", {{"min", {s.bounds.min().x(), s.bounds.min().y(), s.bounds.min().z()}},
                                    {"max", {s.bounds.max().x(), s.bounds.max().y(), s.bounds.max().z()}}}},
                     {"modulus_mpa", {{"min", s.modulusMin}, {"max", s.modulusMax}}},
                     {"sections", {{"circle", s.circles}, {"ellipse", s.ellipses}, {"rectangle", s.rectangles}}},
                     {"caps", {{"round", s.roundCaps}, {"flat", s.flatCaps}}},
                     {"frame_error_rad", s.frameError}};
    std::cout << j.dump(2) << '\n';
    return kOk;
  }
  const geometry::Vec3 size = s.bounds.sizes();
  std::printf("design:        %s\n", file.c_str());
  std::printf("rods:          %zu\n", s.rodCount);
  std::printf("sections:      %zu circle, %zu ellipse, %zu rectangle\n", s.circles, s.ellipses, s.rectangles);
  std::printf("caps:          %zu round, %zu flat\n", s.roundCaps, s.flatCaps);
  std::printf("centerlines:   %.3f mm in total\n", s.totalLength);
  std::printf("bounding box:  %s .. %s mm\n", formatPoint(s.bounds.min()).c_str(), formatPoint(s.bounds.max()).c_str());
  std::printf("size:          %.3f x %.3f x %.3f mm\n", size.x(), size.y(), size.z());
  std::printf("modulus E(s):  %.3f .. %.3f MPa\n", s.modulusMin, s.modulusMax);
  std::printf("frames:        rotation-minimizing ones within %.1e rad of exact (estimated)\n", s.frameError);
  std::printf("valid:         yes\n");
  return kOk;
}

}  // namespace rodfab::cli
