// What the commands that write print jobs (slice, coupons) share: their output, dithering and
// streaming options, the ditherer they name, the progress of the bands, the lines and JSON of their
// summaries, and taking back a job a signal came too late for.
#pragma once

#include "materials/ditherer.hpp"
#include "printer_profiles/job_writer.hpp"
#include "slicer/options.hpp"
#include "slicer/progress.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

namespace rodfab::cli {

// 1234567 -> "1,234,567".
std::string formatCount(std::uint64_t n);

// Declares --output, --format, --image-format, --force, --quiet, --json, --band-layers (0 =
// automatic, see slicer::automaticBandLayers) and --threads.
void addJobOutputOptions(po::options_description& options);

// Declares --dither (`defaultDither`, or no default when null: the command chooses) and --seed.
void addDitherOptions(po::options_description& options, const char* defaultDither, const std::string& ditherHelp);

// What addJobOutputOptions declares, checked. `job.checkInterrupt` throws common::Interrupted on a
// pending signal (the writer asks right before and after renaming the job into place).
struct JobCommandOptions {
  printer_profiles::JobOptions job;
  std::string format;  // "zip" | "dir", as given
  int threads = 0;     // 0: all cores
  int bandLayers = 0;  // 0: automatic
  bool quiet = false, json = false;
};

// Fills `out` from --output, --force, --format (zip | dir), --image-format (bmp | png) and, for the
// commands that declare it, --support (printer | explicit). Returns the usage error for a bad value
// (the caller prints it and exits with kUsage), or nullopt.
std::optional<std::string> parseJobOptions(const po::variables_map& vm, printer_profiles::JobOptions& out);

// Everything addJobOutputOptions declares; nullopt after printing a usage error for `command`.
std::optional<JobCommandOptions> jobCommandOptions(const std::string& command, const po::variables_map& vm);

// The ditherer `name` names, as calibration data and manifests spell them (materials::canonicalDitherName:
// "random" is "white"), seeded with --seed; nullptr after printing a usage error for `command`.
std::unique_ptr<materials::Ditherer> ditherFromName(const std::string& command, const std::string& name,
                                                    const po::variables_map& vm);

// The progress of a job's bands on stderr (Progress, in layers), made at the first band, when the
// part's layer count is known. finish() prints the final line; destroyed unfinished (an interrupt, an
// error) it only ends the bar's line, so the message that follows starts on its own line and no
// "done" is claimed for layers that were not sliced.
class BandProgress {
public:
  explicit BandProgress(bool quiet) : mode_(Progress::detect(quiet)) {}
  ~BandProgress() {
    if (progress_) progress_->stop();
  }
  BandProgress(const BandProgress&) = delete;
  BandProgress& operator=(const BandProgress&) = delete;
  void update(int done, int total);
  void finish();

private:
  Progress::Mode mode_;
  std::unique_ptr<Progress> progress_;
};

// The summary lines both job commands print, labels padded to `width` columns: the job (path,
// format, files, MB), the printer, the layers and images, one line per material.
void printJobLine(const printer_profiles::JobResult& job, const std::string& format, int width);
void printPrinterLine(const printer_profiles::Profile& profile, int width);
void printLayersLine(const printer_profiles::JobResult& job, const printer_profiles::Profile& profile, int width);
void printMaterialLines(const printer_profiles::JobResult& job);

// Per material, as written (JobResult) or as counted back from a job's images (InspectReport): name,
// role, voxels, volume_ml, mass_g.
nlohmann::json materialTotalsJson(const std::vector<printer_profiles::MaterialTotals>& materials);

// The same in --json: job, profile, layers, image_size, print_height_mm, materials, files, bytes.
nlohmann::json jobJson(const printer_profiles::JobResult& job, const printer_profiles::Profile& profile);

// The exit code once the summary is printed: kOk, or for a signal that came after the job was renamed
// into place (README: an interrupted command writes no job) 128 + signal, after withdrawing the job.
int finishJob(const std::string& command, const printer_profiles::JobResult& job);

}  // namespace rodfab::cli
