// rodfab slice: a design into a print job (slicer/slice_design.hpp does the work; the summary is
// slicer/slice_summary.hpp).
#include "common/interrupt.hpp"
#include "common/json_input.hpp"
#include "common/sha256.hpp"
#include "common/stopwatch.hpp"
#include "printer_profiles/job_layout.hpp"
#include "slicer/calibration_option.hpp"
#include "slicer/command.hpp"
#include "slicer/job_options.hpp"
#include "slicer/profile_option.hpp"
#include "slicer/slice_summary.hpp"

#include <chrono>
#include <filesystem>
#include <iostream>

namespace rodfab::cli {

namespace {

Parsed<JobCommandOptions> parseSlice(const std::vector<std::string>& args, po::variables_map& vm) {
  po::options_description options("options");
  options.add_options()("design", po::value<std::string>()->required()->value_name("DESIGN.json"), "design file (rodfab.design/1 JSON)");
  addJobOutputOptions(options);
  options.add_options()("support", po::value<std::string>()->value_name("printer|explicit"), "printer | explicit (default: the profile's)");
  addCalibrationOptions(options);
  addDitherOptions(options, nullptr,
                   "white | blue | error-diffusion (default: the ditherer the calibration coupons were printed with)");
  addProfileOptions(options);
  if (auto code = parseOptionsWithInput("slice", options, "design", args, vm)) return *code;
  std::optional<JobCommandOptions> job = jobCommandOptions("slice", vm);
  if (!job) return kUsage;
  return *std::move(job);
}

// --dither, or the ditherer the calibration's coupons were printed with (white when it does not say);
// a warning when they differ, printed and kept for the job's report. nullptr after a usage error.
std::unique_ptr<materials::Ditherer> chooseDitherer(const po::variables_map& vm, const ChosenCalibration& cal,
                                                    std::vector<std::string>& warnings) {
  const std::string name = vm.count("dither") ? vm["dither"].as<std::string>() : (cal.couponDither.empty() ? "white" : cal.couponDither);
  std::unique_ptr<materials::Ditherer> ditherer = ditherFromName("slice", name, vm);
  if (ditherer && !cal.couponDither.empty() && cal.couponDither != ditherer->name()) {
    warnings.push_back(cal.fileName + " was measured on coupons dithered '" + cal.calibration.record().dither + "', this job dithers '" +
                       std::string(ditherer->name()) +
                       "': a mix's stiffness depends on its dithering, so print and fit coupons with this ditherer (rodfab coupons)");
    std::cerr << "rodfab slice: warning: " << warnings.back() << '\n';
  }
  return ditherer;
}

slicer::SliceSettings sliceSettings(const std::string& designFile, const ChosenCalibration& cal, std::uint64_t seed,
                                    const JobCommandOptions& o) {
  slicer::SliceSettings settings;
  // Jobs name their inputs by file name and SHA-256: no path of this machine travels with them.
  settings.designFile = std::filesystem::path(designFile).filename().string();
  settings.designSha256 = common::sha256Hex(common::readBoundedFile(designFile));
  settings.calibrationFile = cal.fileName;
  settings.calibrationSha256 = cal.sha256;
  settings.calibrationWarning = cal.materialsWarning;
  settings.seed = seed;
  settings.threads = o.threads;
  settings.bandLayers = o.bandLayers;
  settings.job = o.job;
  return settings;
}

// sliceDesign, with what is wrong with the design itself (too large for the tray, too thin to have a
// voxel) said of its file.
slicer::SliceReport sliceDesignFile(const std::string& designFile, const geometry::RodStructure& design,
                                    const printer_profiles::Profile& profile, const ChosenCalibration& cal,
                                    materials::Ditherer& ditherer, const slicer::SliceSettings& settings) {
  try {
    return slicer::sliceDesign(design, profile, cal.calibration, ditherer, settings);
  } catch (const printer_profiles::TrayFitError& e) {
    throw std::runtime_error(designFile + ": " + e.what() + "; no job was written");
  } catch (const printer_profiles::EmptyPartError& e) {
    throw std::runtime_error(designFile + ": " + e.what() + " (no voxel centre of " + profile.name +
                             " lies inside a rod: the rods are thinner than its voxels); no job was written");
  }
}

// The job: every input checked before anything is written, then sliced, summarized; the exit code.
int slice(const po::variables_map& vm, const JobCommandOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  // One limit for every stage (TBB arenas, the writer's encoders); results do not depend on it.
  const ThreadLimit threadLimit(options.threads);

  // Inputs: every one is checked before anything is written.
  const std::string designFile = vm["design"].as<std::string>();
  commandLineAccepted();
  const std::optional<geometry::RodStructure> design = readDesignOrReport(designFile, "no job was written");
  if (!design) return kFailed;
  int profileFailure = kFailed;
  const std::optional<printer_profiles::Profile> profile = profileFromOptions(vm, "slice", "no job was written", profileFailure);
  if (!profile) return profileFailure;
  const std::optional<ChosenCalibration> cal = calibrationFromOptions("slice", vm, *profile);
  if (!cal) return kFailed;
  std::vector<std::string> inputWarnings;
  const std::unique_ptr<materials::Ditherer> ditherer = chooseDitherer(vm, *cal, inputWarnings);
  if (!ditherer) return kUsage;

  // The output is refused now (a user's folder, a job without --force) rather than after the work.
  warnLeftoverPreviousVersions(options.job.output);
  printer_profiles::checkJobOutput(options.job);
  common::installInterruptHandlers();
  SliceSummary summary{designFile, design->rods.size(), &*profile, &*cal, std::string(ditherer->name()),
                       vm["seed"].as<Seed>().value};
  slicer::SliceSettings settings = sliceSettings(designFile, *cal, summary.seed, options);
  settings.inputWarnings = std::move(inputWarnings);
  BandProgress progress(options.quiet);
  settings.onBand = [&](int done, int total) {
    progress.update(done, total);
    common::throwIfInterrupted();
  };
  summary.inputSeconds = common::secondsSince(start);
  const slicer::SliceReport report = sliceDesignFile(designFile, *design, *profile, *cal, *ditherer, settings);
  progress.finish();
  summary.totalSeconds = common::secondsSince(start);
  summary.inputSeconds += report.prepareSeconds;
  common::registerCleanup(report.job.path);  // until the command returns, a signal still removes the job
  printSliceSummary(summary, report, options);
  return finishJob("slice", report.job);
}

}  // namespace

int runSlice(const std::vector<std::string>& args) {
  po::variables_map vm;
  return runParsed(parseSlice(args, vm), [&](const JobCommandOptions& options) { return slice(vm, options); });
}

}  // namespace rodfab::cli
