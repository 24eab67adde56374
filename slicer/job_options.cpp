#include "slicer/job_options.hpp"

#include "common/interrupt.hpp"

#include <cstdio>
#include <iostream>
#include <stdexcept>

namespace rodfab::cli {

std::string formatCount(std::uint64_t n) {
  const std::string digits = std::to_string(n);
  std::string out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

void addJobOutputOptions(po::options_description& options) {
  options.add_options()
      ("output,o", po::value<std::string>()->required()->value_name("JOB.zip|JOB.gcvf"), "the job: NAME.zip, or a folder with --format dir")
      ("format", po::value<std::string>()->default_value("zip")->value_name("zip|dir"), "zip | dir")
      ("image-format", po::value<std::string>()->value_name("bmp|png"), "bmp | png (default: the profile's)")
      ("band-layers", po::value<int>()->default_value(0)->value_name("N"),
       "layers per streamed band (0 = automatic: 64, fewer for parts with large layers, to bound memory)")
      ("force", "replace an existing job at --output")
      ("quiet,q", "no progress bar or progress lines and no notes on stderr (the summary, warnings and errors are still printed)")
      ("json", "print the job summary as JSON on stdout");
  addThreadsOption(options, "the job is the same for any count");
}

void addDitherOptions(po::options_description& options, const char* defaultDither, const std::string& ditherHelp) {
  auto* dither = po::value<std::string>()->value_name("white|blue|error-diffusion");
  if (defaultDither) dither->default_value(defaultDither);
  options.add_options()("dither", dither, ditherHelp.c_str());
  options.add_options()("seed", po::value<Seed>()->default_value(Seed{0})->value_name("N"), "dithering seed");
}

std::optional<std::string> parseJobOptions(const po::variables_map& vm, printer_profiles::JobOptions& out) {
  out.output = vm["output"].as<std::string>();
  out.force = vm.count("force") > 0;
  const std::string format = vm["format"].as<std::string>();
  if (format == "zip") out.archive = printer_profiles::ArchiveFormat::Zip;
  else if (format == "dir") out.archive = printer_profiles::ArchiveFormat::Directory;
  else return "--format: expected zip or dir, got '" + format + "'";
  try {
    if (vm.count("image-format")) out.imageFormat = printer_profiles::parseImageFormat(vm["image-format"].as<std::string>());
    if (vm.count("support")) out.support = printer_profiles::parseSupportPolicy(vm["support"].as<std::string>());
  } catch (const std::invalid_argument& e) {
    return std::string(e.what());
  }
  return std::nullopt;
}

std::optional<JobCommandOptions> jobCommandOptions(const std::string& command, const po::variables_map& vm) {
  JobCommandOptions o;
  const std::optional<int> threads = threadCount(command, vm);
  if (!threads) return std::nullopt;
  const std::optional<int> bandLayers = intOption(command, vm, "band-layers", 0, kMaxBandLayers);
  if (!bandLayers) return std::nullopt;
  if (const std::optional<std::string> error = parseJobOptions(vm, o.job)) {
    usageError(command, *error);
    return std::nullopt;
  }
  o.job.checkInterrupt = [] { common::throwIfInterrupted(); };
  o.format = vm["format"].as<std::string>();
  o.threads = *threads;
  o.bandLayers = *bandLayers;
  o.quiet = vm.count("quiet") > 0;
  o.json = vm.count("json") > 0;
  return o;
}

std::unique_ptr<materials::Ditherer> ditherFromName(const std::string& command, const std::string& name,
                                                    const po::variables_map& vm) {
  materials::DitherOptions options;
  options.seed = vm["seed"].as<Seed>().value;
  options.checkInterrupt = [] { common::throwIfInterrupted(); };  // a band of error diffusion takes seconds
  try {
    return materials::makeDitherer(materials::canonicalDitherName(name), options);
  } catch (const std::invalid_argument& e) {
    usageError(command, std::string("--dither: ") + e.what());
    return nullptr;
  }
}

void BandProgress::update(int done, int total) {
  if (!progress_) progress_ = std::make_unique<Progress>("layers", static_cast<std::size_t>(total), mode_, std::cerr);
  progress_->update(static_cast<std::size_t>(done));
}

void BandProgress::finish() {
  if (progress_) progress_->finish();
}

namespace {

std::string label(const char* name, int width) {
  std::string text = std::string(name) + ':';
  if (static_cast<int>(text.size()) < width) text.append(static_cast<std::size_t>(width) - text.size(), ' ');
  return text;
}

double printHeightMm(const printer_profiles::JobResult& job, const printer_profiles::Profile& profile) {
  return job.geometry.layers * profile.layerThicknessMm();
}

}  // namespace

void printJobLine(const printer_profiles::JobResult& job, const std::string& format, int width) {
  std::printf("%s%s (%s, %zu files, %.1f MB)\n", label("job", width).c_str(), job.path.c_str(), format.c_str(), job.files,
              static_cast<double>(job.bytes) / 1e6);
}

void printPrinterLine(const printer_profiles::Profile& profile, int width) {
  std::printf("%s%s (%s)\n", label("printer", width).c_str(), profile.printer.c_str(), profile.name.c_str());
}

void printLayersLine(const printer_profiles::JobResult& job, const printer_profiles::Profile& profile, int width) {
  const printer_profiles::JobGeometry& g = job.geometry;
  std::printf("%s%d x %.3f mm = %.2f mm print height; images %d x %d px\n", label("layers", width).c_str(), g.layers,
              profile.layerThicknessMm(), printHeightMm(job, profile), g.width, g.height);
}

void printMaterialLines(const printer_profiles::JobResult& job) {
  for (const auto& m : job.materials)
    std::printf("  %-14s %-8s %15s voxels  %9.3f mL  %9.3f g\n", m.name.c_str(), printer_profiles::toString(m.role),
                formatCount(m.voxels).c_str(), m.volumeMl, m.massG);
}

nlohmann::json materialTotalsJson(const std::vector<printer_profiles::MaterialTotals>& materials) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& m : materials)
    out.push_back({{"name", m.name}, {"role", printer_profiles::toString(m.role)}, {"voxels", m.voxels},
                   {"volume_ml", m.volumeMl}, {"mass_g", m.massG}});
  return out;
}

nlohmann::json jobJson(const printer_profiles::JobResult& job, const printer_profiles::Profile& profile) {
  const printer_profiles::JobGeometry& g = job.geometry;
  return {{"job", job.path.string()},
          {"profile", profile.name},
          {"layers", g.layers},
          {"image_size", {g.width, g.height}},
          {"print_height_mm", printHeightMm(job, profile)},
          {"materials", materialTotalsJson(job.materials)},
          {"files", job.files},
          {"bytes", job.bytes}};
}

int finishJob(const std::string& command, const printer_profiles::JobResult& job) {
  const int signal = common::interruptRequested();
  if (!signal) return 0;
  printer_profiles::withdrawJob(job);
  std::cerr << "rodfab " << command << ": " << common::Interrupted(signal).what() << '\n';
  return 128 + signal;
}

}  // namespace rodfab::cli
