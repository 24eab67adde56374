// rodfab coupons: the print job for DMA calibration bars, one uniform bar per Vero fraction, dithered
// with the ditherer the real jobs will use (a mix's stiffness depends on it), each bar labelled in the
// manifest (metadata.coupons) so the measurements can be traced back to fraction and ditherer. The
// bars themselves: slicer/coupon_layout.hpp.
#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "common/stopwatch.hpp"
#include "printer_profiles/printer_profiles.hpp"
#include "slicer/command.hpp"
#include "slicer/coupon_layout.hpp"
#include "slicer/coupon_summary.hpp"
#include "slicer/job_options.hpp"
#include "slicer/profile_option.hpp"
#include "slicer/slice_design.hpp"
#include "slicer/value_parsers.hpp"

#include <chrono>
#include <iostream>

namespace rodfab::cli {

namespace {

constexpr std::size_t kMaxCoupons = 1000;

Parsed<CouponRequest> parseCoupons(const std::vector<std::string>& args, po::variables_map& vm) {
  po::options_description options("options");
  addJobOutputOptions(options);
  options.add_options()
      ("fractions", po::value<std::string>()->default_value("0,0.1,...,1")->value_name("A,B,...,Z"),
       "Vero fractions of the bars, comma-separated; A,B,...,Z continues the step B - A up to Z")
      ("size", po::value<std::string>()->default_value("30x5x1.5")->value_name("LxWxH"), "bar size LENGTHxWIDTHxHEIGHT in millimetres (length along x)")
      ("gap", po::value<double>()->default_value(5.0)->value_name("MM"), "gap between bars in mm, along x and y");
  addDitherOptions(options, "white", "white (random, as published) | blue | error-diffusion: the ditherer the jobs will use");
  addProfileOptions(options);
  if (auto code = parseOptions("coupons", options, {}, args, vm)) return *code;
  std::optional<JobCommandOptions> job = jobCommandOptions("coupons", vm);
  if (!job) return kUsage;
  CouponRequest r;
  r.job = *std::move(job);
  try {
    r.fractions = parseFractionList("--fractions", vm["fractions"].as<std::string>(), kMaxCoupons);
    r.sizeMm = parseSizeMm("--size", vm["size"].as<std::string>());
  } catch (const BadValue& e) {
    return usageError("coupons", e.what());
  }
  r.gapMm = vm["gap"].as<double>();
  if (!(r.gapMm > 0.0 && r.gapMm <= 1000.0))
    return usageError("coupons", "--gap: expected a gap in mm, > 0 and at most 1000, got " + formatNumber(r.gapMm));
  r.seed = vm["seed"].as<Seed>().value;
  return r;
}

// The coupons' job: the bars laid out and checked, then streamed and summarized; the exit code.
int makeCoupons(const po::variables_map& vm, const CouponRequest& r) {
  const std::unique_ptr<materials::Ditherer> ditherer = ditherFromName("coupons", vm["dither"].as<std::string>(), vm);
  if (!ditherer) return kUsage;
  const auto start = std::chrono::steady_clock::now();
  const ThreadLimit threadLimit(r.job.threads);
  int profileFailure = kFailed;
  const std::optional<printer_profiles::Profile> profile = profileFromOptions(vm, "coupons", "no job was written", profileFailure);
  if (!profile) return profileFailure;
  int exitCode = kOk;
  const std::optional<slicer::CouponLayout> layout = layOutCoupons(r, *profile, exitCode);
  if (!layout) return exitCode;
  commandLineAccepted();
  const int bandLayers = r.job.bandLayers > 0 ? r.job.bandLayers : slicer::automaticBandLayers(layout->bounds);
  common::requireMemory(slicer::couponJobBytes(*layout, *profile, r.job.job.contactSheetLayers, bandLayers, *ditherer),
                        {.what = "coupons' " + std::to_string(r.fractions.size()) + " bar(s) of " + barText(*layout, *profile),
                         .remedy = "use a smaller --size, fewer --fractions or fewer --band-layers"});
  // The output is refused now (a user's folder, a job without --force) rather than after the work.
  warnLeftoverPreviousVersions(r.job.job.output);
  printer_profiles::checkJobOutput(r.job.job);
  common::installInterruptHandlers();

  slicer::BarCountingDitherer counting(*ditherer, *layout);
  BandProgress progress(r.job.quiet);
  slicer::PipelineOptions pipeline;
  pipeline.bandLayers = bandLayers;
  pipeline.onBand = [&](int done, int total) {
    progress.update(done, total);
    common::throwIfInterrupted();
  };
  nlohmann::json bars;
  pipeline.beforeFinalize = [&](printer_profiles::JobMetadata& metadata) {
    bars = slicer::couponBarsJson(*layout, r.fractions, counting, r.seed, profile->voxelSizeMm);
    metadata.extra["coupons"] = couponsManifest(r, *layout, *profile, bars, std::string(ditherer->name()));
  };
  slicer::StageSeconds seconds;
  const printer_profiles::JobResult job =
      slicer::streamJob(couponJobSpec(r, *profile, *layout, std::string(ditherer->name())),
                        slicer::couponBands(*layout, r.fractions, *profile, couponOriginMm(*profile)), counting, pipeline, seconds);
  common::registerCleanup(job.path);  // until the command returns, a signal still removes the job
  progress.finish();
  printCouponSummary(r, job, *profile, *layout, bars, seconds, common::secondsSince(start));
  return finishJob("coupons", job);
}

}  // namespace

int runCoupons(const std::vector<std::string>& args) {
  po::variables_map vm;
  return runParsed(parseCoupons(args, vm), [&](const CouponRequest& request) { return makeCoupons(vm, request); });
}

}  // namespace rodfab::cli
