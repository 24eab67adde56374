#include "calibration/calibration.hpp"
#include "common/json_input.hpp"
#include "common/sha256.hpp"
#include "geometry/geometry.hpp"
#include "common/stopwatch.hpp"
#include "materials/materials.hpp"
#include "printer_profiles/printer_profiles.hpp"
#include "slicer/command.hpp"
#include "slicer/interrupt.hpp"
#include "slicer/job_options.hpp"
#include "slicer/options.hpp"
#include "slicer/profile_option.hpp"
#include "slicer/calibration_materials.hpp"
#include "slicer/progress.hpp"
#include "slicer/slice_design.hpp"

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

namespace rodfab::cli {

namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

int runSlice(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("design", po::value<std::string>()->required(), "design file (rodfab.design/1 JSON)")
      ("output,o", po::value<std::string>()->required(), "the job: NAME.zip, or a folder with --format dir")
      ("calibration", po::value<std::string>(), "calibration file (rodfab calibrate); default: the bundled 60 C fit")
      ("dither", po::value<std::string>(),
       "white | blue | error-diffusion (default: the ditherer the calibration coupons were printed with)")
      ("seed", po::value<Seed>()->default_value(Seed{0}), "dithering seed")
      ("format", po::value<std::string>()->default_value("zip"), "zip | dir")
      ("image-format", po::value<std::string>(), "bmp | png (default: the profile's)")
      ("support", po::value<std::string>(), "printer | explicit (default: the profile's)")
      ("band-layers", po::value<int>()->default_value(0),
       "layers per streamed band (0 = automatic: 64, fewer for parts with large layers, to bound memory)")
      ("allow-calibration-materials-mismatch",
       "use a calibration measured on other materials than the profile's (the job's moduli are then estimates)")
      ("force", "replace an existing job at --output")
      ("quiet,q", "no progress bar or progress lines and no clamped-moduli note on stderr (the summary, warnings and errors are still printed)")
      ("json", "print the job summary as JSON on stdout");
  addThreadsOption(options, "the job is the same for any count");
  addProfileOptions(options);
  po::positional_options_description positional;
  positional.add("design", 1);
  po::variables_map vm;
  const char* synopsis =
      "DESIGN.json --output JOB.zip [--profile NAME|FILE] [--print-mode MODE] [--calibration CAL.json] [--dither white|blue|error-diffusion] "
      "[--seed N] [--threads N] [--format zip|dir] [--image-format bmp|png] [--support printer|explicit] [--allow-calibration-materials-mismatch] [--force] [--quiet] [--json]";
  if (auto code = parseOptions("slice", synopsis, options, positional, args, vm)) return *code;

  const auto usageError = [](const std::string& message) { return cli::usageError("slice", message); };
  const std::optional<int> threadsOption = threadCount("slice", vm);
  if (!threadsOption) return kUsage;
  const int threads = *threadsOption;
  const std::optional<int> bandOption = intOption("slice", vm, "band-layers", 0, kMaxBandLayers);
  if (!bandOption) return kUsage;
  const int bandLayers = *bandOption;
  printer_profiles::JobOptions jobOptions;
  if (auto error = parseJobOptions(vm, jobOptions)) return usageError(*error);
  // The writer asks again right before and right after renaming the job into place (README: an
  // interrupted command writes no job).
  jobOptions.checkInterrupt = [] { throwIfInterrupted(); };
  const std::string format = vm["format"].as<std::string>();

  const auto tStart = Clock::now();
  double readSeconds = 0.0;
  // One limit for every stage (TBB arenas, the writer's encoders); results do not depend on it.
  std::unique_ptr<tbb::global_control> threadLimit;
  if (threads > 0)
    threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);

  // Inputs: every one is checked before anything is written.
  const std::string designFile = vm["design"].as<std::string>();
  commandLineAccepted();
  const std::optional<geometry::RodStructure> read = readDesignOrReport(designFile, "no job was written");
  if (!read) return kFailed;
  const geometry::RodStructure& design = *read;
  const std::optional<printer_profiles::Profile> profileOption = profileFromOptions(vm, "no job was written");
  if (!profileOption) return kFailed;
  const printer_profiles::Profile& profile = *profileOption;
  const std::string calibrationFile =
      vm.count("calibration") ? vm["calibration"].as<std::string>() : calibration::defaultCalibrationPath().string();
  std::string calibrationSha256;
  const calibration::Calibration cal = calibration::readCalibration(calibrationFile, &calibrationSha256);
  const slicer::CalibrationMaterialsCheck materialsCheck = slicer::checkCalibrationMaterials(
      // By file name: the message also goes into the manifest, which holds no path of this machine.
      cal, std::filesystem::path(calibrationFile).filename().string(), profile, !vm.count("calibration"),
      vm.count("allow-calibration-materials-mismatch") > 0);
  if (materialsCheck.refused) {
    std::cerr << "rodfab slice: " << materialsCheck.message << "\nno job was written\n";
    return kFailed;
  }
  const std::string couponDither = materials::canonicalDitherName(cal.record().dither);
  const std::string ditherName = vm.count("dither") ? vm["dither"].as<std::string>() : (couponDither.empty() ? "white" : couponDither);
  materials::DitherOptions ditherOptions;
  ditherOptions.seed = vm["seed"].as<Seed>().value;
  std::unique_ptr<materials::Ditherer> ditherer;
  try {
    ditherer = materials::makeDitherer(ditherName, ditherOptions);
  } catch (const std::invalid_argument& e) {
    return usageError(std::string("--dither: ") + e.what());
  }
  if (!couponDither.empty() && couponDither != ditherer->name())
    std::cerr << "rodfab slice: warning: " << calibrationFile << " was measured on coupons dithered '" << cal.record().dither
              << "', this job dithers '" << ditherer->name()
              << "': a mix's stiffness depends on its dithering, so print and fit coupons with this ditherer (rodfab coupons)\n";

  // The output is refused now (a user's folder, a job without --force) rather than after the work.
  printer_profiles::checkJobOutput(jobOptions);
  InterruptGuard interrupts;
  const Progress::Mode mode = Progress::detect(vm.count("quiet") > 0);
  std::unique_ptr<Progress> progress;
  slicer::SliceSettings settings;
  // Jobs name their inputs by file name and SHA-256: no path of this machine travels with them.
  settings.designFile = std::filesystem::path(designFile).filename().string();
  settings.designSha256 = common::sha256Hex(common::readBoundedFile(designFile));
  settings.calibrationFile = std::filesystem::path(calibrationFile).filename().string();
  settings.calibrationSha256 = calibrationSha256;
  settings.calibrationWarning = materialsCheck.message;
  settings.seed = ditherOptions.seed;
  settings.threads = threads;
  settings.bandLayers = bandLayers;
  settings.job = jobOptions;
  settings.onBand = [&](int done, int total) {
    if (!progress) progress = std::make_unique<Progress>("layers", static_cast<std::size_t>(total), mode, std::cerr);
    progress->update(static_cast<std::size_t>(done));
    throwIfInterrupted();
  };
  readSeconds = common::secondsSince(tStart);

  slicer::SliceReport report;
  try {
    report = slicer::sliceDesign(design, profile, cal, *ditherer, settings);
  } catch (const Interrupted& e) {
    if (progress) progress->finish();
    std::cerr << "rodfab slice: " << e.what() << '\n';
    return 128 + e.signal;
  }
  if (progress) progress->finish();
  const double total = common::secondsSince(tStart);
  const printer_profiles::JobResult& job = report.job;
  common::registerCleanup(job.path);  // until the command returns, a signal still removes the job
  const materials::MappingStats& mapping = report.mapping;
  const slicer::StageSeconds& seconds = report.seconds;
  const double supportSeconds = report.supportSeconds;
  readSeconds += report.prepareSeconds;

  std::uint64_t rodsWithoutVoxels = 0;
  for (std::uint64_t n : report.voxelsPerRod) rodsWithoutVoxels += n == 0;
  const printer_profiles::JobGeometry& g = job.geometry;
  const double heightMm = g.layers * profile.layerThicknessMm();
  if (vm.count("json")) {
    nlohmann::json materialsJson = nlohmann::json::array();
    for (const auto& m : job.materials)
      materialsJson.push_back({{"name", m.name}, {"role", printer_profiles::toString(m.role)}, {"voxels", m.voxels},
                               {"volume_ml", m.volumeMl}, {"mass_g", m.massG}});
    const nlohmann::json j{
        {"job", job.path.string()},
        {"design", designFile},
        {"profile", profile.name},
        {"layers", g.layers},
        {"image_size", {g.width, g.height}},
        {"print_height_mm", heightMm},
        {"voxels", mapping.voxels},
        {"materials", materialsJson},
        {"ditherer", std::string(ditherer->name())},
        {"seed", ditherOptions.seed},
        {"calibration", {{"file", settings.calibrationFile}, {"sha256", calibrationSha256}}},
        {"calibration_warning", materialsCheck.message.empty() ? nlohmann::json(nullptr) : nlohmann::json(materialsCheck.message)},
        {"clamped_moduli", {{"below_floor", mapping.clamps.belowFloor}, {"above_max", mapping.clamps.aboveMax},
                            {"floor_mpa", report.floorMpa}, {"max_mpa", report.maxModulusMpa}}},
        {"rods_without_voxels", rodsWithoutVoxels},
        {"files", job.files},
        {"bytes", job.bytes},
        {"seconds", {{"inputs", readSeconds}, {"support", supportSeconds}, {"voxelize_and_map", seconds.source},
                     {"dither", seconds.dither}, {"emit", seconds.emit}, {"total", total}}}};
    std::cout << j.dump(2) << '\n';
  } else {
    std::printf("job:            %s (%s, %zu files, %.1f MB)\n", job.path.c_str(), format.c_str(), job.files,
                static_cast<double>(job.bytes) / 1e6);
    std::printf("design:         %s (%zu rods)\n", designFile.c_str(), design.rods.size());
    std::printf("printer:        %s (%s)\n", profile.printer.c_str(), profile.name.c_str());
    std::printf("layers:         %d x %.3f mm = %.2f mm print height; images %d x %d px\n", g.layers,
                profile.layerThicknessMm(), heightMm, g.width, g.height);
    std::printf("voxels:         %s model voxels\n", formatCount(mapping.voxels).c_str());
    for (const auto& m : job.materials)
      std::printf("  %-14s %-8s %15s voxels  %9.3f mL  %9.3f g\n", m.name.c_str(), printer_profiles::toString(m.role),
                  formatCount(m.voxels).c_str(), m.volumeMl, m.massG);
    std::printf("dithering:      %s, seed %llu\n", std::string(ditherer->name()).c_str(),
                static_cast<unsigned long long>(ditherOptions.seed));
    std::printf("calibration:    %s, sha256 %.12s... (floor %.3g MPa = %.1f %% Vero, max %.4g MPa)\n",
                settings.calibrationFile.c_str(), calibrationSha256.c_str(), report.floorMpa, 100.0 * report.floorFraction,
                report.maxModulusMpa);
    if (!materialsCheck.message.empty()) std::printf("                WARNING: %s\n", materialsCheck.message.c_str());
    std::printf("clamped moduli: %s below the floor, %s above the stiffest mix\n",
                formatCount(mapping.clamps.belowFloor).c_str(), formatCount(mapping.clamps.aboveMax).c_str());
    std::printf("time:           %.2f s inputs, %.2f s support, %.2f s voxelize + map, %.2f s dither, %.2f s emit; %.2f s total\n",
                readSeconds, supportSeconds, seconds.source, seconds.dither, seconds.emit, total);
  }
  if (!materialsCheck.message.empty()) std::cerr << "rodfab slice: warning: " << materialsCheck.message << '\n';
  for (const std::string& warning : report.warnings) std::cerr << "rodfab slice: warning: " << warning << '\n';
  if (rodsWithoutVoxels > 0)
    std::cerr << "rodfab slice: warning: " << rodsWithoutVoxels
              << " rod(s) hold no voxel centre (thinner than the voxel or hidden in other rods); rodfab voxelize --json lists them\n";
  if (mapping.clamps.total() > 0 && !vm.count("quiet"))
    std::cerr << "rodfab slice: note: " << formatCount(mapping.clamps.total())
              << " voxel(s) asked for a modulus the materials cannot make; they were clamped (see the summary)\n";
  // A signal that came after the job was renamed into place still means no job (README): take it back.
  if (const int signal = InterruptGuard::pending()) {
    printer_profiles::withdrawJob(job);
    std::cerr << "rodfab slice: " << Interrupted(signal).what() << '\n';
    return 128 + signal;
  }
  return kOk;
}

}  // namespace rodfab::cli
