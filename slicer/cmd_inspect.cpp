#include "printer_profiles/printer_profiles.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <cstdio>
#include <iostream>

namespace rodfab::cli {

namespace pp = printer_profiles;

int runInspect(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("job", po::value<std::string>()->required(), "the job: a .zip archive or a directory written by rodfab")
      ("json", "print the report as JSON on stdout");
  po::positional_options_description positional;
  positional.add("job", 1);
  po::variables_map vm;
  if (auto code = parseOptions("inspect", "JOB [--json]", options, positional, args, vm)) return *code;
  commandLineAccepted();

  const pp::InspectReport report = pp::inspectJob(vm["job"].as<std::string>());
  if (vm.count("json")) {
    nlohmann::json materials = nlohmann::json::array();
    for (const auto& m : report.materials)
      materials.push_back({{"name", m.name}, {"role", pp::toString(m.role)}, {"voxels", m.voxels},
                           {"volume_ml", m.volumeMl}, {"mass_g", m.massG}});
    nlohmann::json out{{"job", report.job.string()},
                       {"ok", report.ok()},
                       {"defects", report.defects},
                       {"files_checked", report.filesChecked},
                       {"image", {{"width", report.width}, {"height", report.height}}},
                       {"layers", report.layers},
                       {"materials", materials}};
    std::cout << out.dump(2) << '\n';
    return report.ok() ? kOk : kFailed;
  }
  std::printf("job:           %s\n", report.job.c_str());
  const nlohmann::json& m = report.manifest;
  if (m.is_object() && m.contains("profile") && m["profile"].is_object()) {
    const auto& p = m["profile"];
    std::printf("profile:       %s (%s)\n", p.value("name", "?").c_str(), p.value("printer", "?").c_str());
    std::printf("resolution:    %d x %d dpi (x columns, y rows), %.3f mm layers\n", p.value("x_dpi", 0), p.value("y_dpi", 0),
                p.value("layer_thickness_mm", 0.0));
  }
  if (report.width > 0) {
    std::printf("images:        %d x %d pixels, %d layers", report.width, report.height, report.layers);
    if (m.is_object() && m.contains("image")) std::printf(", 1-bit %s", m["image"].value("format", "?").c_str());
    std::printf("\n");
  }
  if (m.is_object() && m.contains("frame") && m["frame"].contains("part_size_mm")) {
    const auto& s = m["frame"]["part_size_mm"];
    std::printf("part:          %.2f x %.2f x %.2f mm\n", s[0].get<double>(), s[1].get<double>(), s[2].get<double>());
  }
  if (m.is_object() && m.contains("support")) std::printf("support:       %s\n", m["support"].value("policy", "?").c_str());
  if (m.is_object() && m.contains("dithering"))
    std::printf("dithering:     %s, seed %llu\n", m["dithering"].value("ditherer", "?").c_str(),
                static_cast<unsigned long long>(m["dithering"].value("seed", std::uint64_t{0})));
  for (const auto& mat : report.materials)
    std::printf("material:      %-16s %-8s %12llu voxels %10.3f mL %10.3f g\n", mat.name.c_str(), pp::toString(mat.role),
                static_cast<unsigned long long>(mat.voxels), mat.volumeMl, mat.massG);
  std::printf("files checked: %zu\n", report.filesChecked);
  for (const std::string& d : report.defects) std::fprintf(stderr, "defect: %s\n", d.c_str());
  std::printf("verdict:       %s\n", report.ok() ? "OK" : "DEFECTIVE");
  return report.ok() ? kOk : kFailed;
}

}  // namespace rodfab::cli
