#include "printer_profiles/printer_profiles.hpp"
#include "slicer/command.hpp"
#include "slicer/job_options.hpp"
#include "slicer/options.hpp"

#include <cstdio>
#include <iostream>

namespace rodfab::cli {

namespace pp = printer_profiles;

namespace {

nlohmann::json reportJson(const pp::InspectReport& report) {
  const pp::InspectSummary& s = report.summary;
  return {{"job", report.job.string()},
          {"ok", report.ok()},
          {"checked", report.checked()},
          {"not_checked", report.checked() ? nlohmann::json() : nlohmann::json(report.notChecked)},
          {"defects", report.defects},
          {"profile", s.profile},
          {"files_checked", report.filesChecked},
          {"blank_copies_compared_stored", report.blankCopiesComparedStored},
          {"image", {{"width", report.width}, {"height", report.height}, {"format", s.imageFormat}}},
          {"layers", report.layers},
          {"support", s.supportPolicy},
          {"materials", materialTotalsJson(report.materials)}};
}

// Every value printed comes from the report's checked summary, never from the raw manifest.
void printReport(const pp::InspectReport& report) {
  const pp::InspectSummary& s = report.summary;
  std::printf("job:           %s\n", report.job.c_str());
  if (!s.profile.empty()) {
    std::printf("profile:       %s (%s)\n", s.profile.c_str(), s.printer.c_str());
    std::printf("resolution:    %d x %d dpi (x columns, y rows), %.3f mm layers\n", s.xDpi, s.yDpi, s.layerThicknessMm);
  }
  if (report.width > 0)
    std::printf("images:        %d x %d pixels, %d layers, %d-bit %s\n", report.width, report.height, report.layers, s.bitDepth,
                s.imageFormat.c_str());
  if (s.partSizeMm) std::printf("part:          %.2f x %.2f x %.2f mm\n", (*s.partSizeMm)[0], (*s.partSizeMm)[1], (*s.partSizeMm)[2]);
  if (!s.supportPolicy.empty()) std::printf("support:       %s\n", s.supportPolicy.c_str());
  if (!s.ditherer.empty() && s.seed)
    std::printf("dithering:     %s, seed %llu\n", s.ditherer.c_str(), static_cast<unsigned long long>(*s.seed));
  for (const auto& mat : report.materials)
    std::printf("material:      %-16s %-8s %12llu voxels %10.3f mL %10.3f g\n", mat.name.c_str(), pp::toString(mat.role),
                static_cast<unsigned long long>(mat.voxels), mat.volumeMl, mat.massG);
  if (report.blankCopiesComparedStored > 0)
    std::printf("files checked: %zu (%zu of them copies of a checked blank layer image, compared as stored)\n", report.filesChecked,
                report.blankCopiesComparedStored);
  else
    std::printf("files checked: %zu\n", report.filesChecked);
  for (const std::string& d : report.defects) std::fprintf(stderr, "defect: %s\n", d.c_str());
  if (!report.checked()) std::fprintf(stderr, "not checked: %s: %s\n", report.job.c_str(), report.notChecked.c_str());
  // Defects found without the profile are defects of any job; otherwise a job that could not be
  // checked is neither sound nor defective.
  std::printf("verdict:       %s\n", !report.defects.empty() ? "DEFECTIVE" : report.checked() ? "OK" : "NOT CHECKED");
}

}  // namespace

int runInspect(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("job", po::value<std::string>()->required()->value_name("JOB"), "the job: a .zip archive or a directory written by rodfab")
      ("profile", po::value<std::string>()->value_name("NAME|FILE"),
       "check against this printer profile (a bundled name or a profile file); default: the bundled profile the "
       "job's manifest names (a manifest never chooses a file)")
      ("json", "print the report as JSON on stdout");
  po::variables_map vm;
  if (auto code = parseOptionsWithInput("inspect", options, "job", args, vm)) return *code;
  commandLineAccepted();

  pp::InspectOptions inspectOptions;
  if (vm.count("profile")) {
    try {
      inspectOptions.profile = pp::loadProfile(vm["profile"].as<std::string>());
    } catch (const pp::ProfileError& e) {
      std::cerr << e.what() << "\n";
      return kFailed;
    }
  }
  const pp::InspectReport report = pp::inspectJob(vm["job"].as<std::string>(), inspectOptions);
  if (vm.count("json")) std::cout << reportJson(report).dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << '\n';
  else printReport(report);
  return report.ok() ? kOk : kFailed;
}

}  // namespace rodfab::cli
