#include "slicer/coupon_summary.hpp"

#include "printer_profiles/printer_profiles.hpp"
#include "slicer/command.hpp"
#include "slicer/job_report.hpp"
#include "slicer/options.hpp"
#include "slicer/value_parsers.hpp"

#include <cstdio>
#include <iostream>
#include <stdexcept>

namespace rodfab::cli {

namespace {

std::array<double, 3> barMm(const slicer::CouponLayout& layout, const printer_profiles::Profile& profile) {
  const std::array<double, 3>& v = profile.voxelSizeMm;
  return {layout.bar.x() * v[0], layout.bar.y() * v[1], layout.bar.z() * v[2]};
}

nlohmann::json coord(const openvdb::Coord& c) { return {c.x(), c.y(), c.z()}; }

constexpr int kLabel = 13;  // the label column of the summary lines

void printCouponLines(const CouponRequest& r, const printer_profiles::JobResult& job, const printer_profiles::Profile& profile,
                      const slicer::CouponLayout& layout, const nlohmann::json& bars) {
  const std::string& dither = bars.empty() ? std::string() : bars[0]["ditherer"].get_ref<const std::string&>();
  printJobLine(job, r.job.format, kLabel);
  printPrinterLine(profile, kLabel);
  std::printf("coupons:     %zu bars of %s (%d x %d x %d voxels; asked %s x %s x %s mm), %s mm gaps; %d row%s of %d\n",
              r.fractions.size(), barText(layout, profile).c_str(), layout.bar.x(), layout.bar.y(), layout.bar.z(),
              formatNumber(r.sizeMm[0]).c_str(), formatNumber(r.sizeMm[1]).c_str(), formatNumber(r.sizeMm[2]).c_str(),
              formatNumber(r.gapMm).c_str(), layout.rows, layout.rows == 1 ? "" : "s", layout.perRow);
  printLayersLine(job, profile, kLabel);
  std::printf("dithering:   %s, seed %llu\n", dither.c_str(), static_cast<unsigned long long>(r.seed));
  std::printf("  bar  specimen   fraction  Vero share   x, y of the min corner (mm)\n");
  for (const nlohmann::json& b : bars)
    std::printf("  %3d  %-9s  %8.3f  %10.4f   %.3f, %.3f\n", b["index"].get<int>(), b["specimen"].get<std::string>().c_str(),
                b["vero_fraction"].get<double>(), b["vero_share"].get<double>(), b["position_mm"][0].get<double>(),
                b["position_mm"][1].get<double>());
  printMaterialLines(job);
}

}  // namespace

openvdb::Vec3d couponOriginMm(const printer_profiles::Profile& profile) {
  const std::array<double, 3>& v = profile.voxelSizeMm;
  return {v[0] / 2, v[1] / 2, v[2] / 2};
}

std::string barText(const slicer::CouponLayout& layout, const printer_profiles::Profile& profile) {
  return slicer::barSizeText(layout, profile.voxelSizeMm);
}

printer_profiles::JobSpec couponJobSpec(const CouponRequest& r, const printer_profiles::Profile& profile,
                                        const slicer::CouponLayout& layout, const std::string& ditherName) {
  printer_profiles::JobSpec spec;
  spec.profile = profile;
  spec.partBounds = layout.bounds;
  spec.originMm = couponOriginMm(profile);
  spec.metadata.ditherer = ditherName;
  spec.metadata.seed = r.seed;
  spec.options = r.job.job;
  // report.html (slicer/job_report.hpp): coupons record no calibration or clamping; the rest applies.
  spec.options.report = [verified = r.job.job.verify](const nlohmann::json& manifest, const auto& previews) {
    slicer::ReportInputs inputs;
    inputs.verified = verified;
    const std::string page = slicer::renderJobReport(manifest, previews, inputs);
    return printer_profiles::Bytes(page.begin(), page.end());
  };
  return spec;
}

nlohmann::json couponsManifest(const CouponRequest& r, const slicer::CouponLayout& layout,
                               const printer_profiles::Profile& profile, const nlohmann::json& bars, const std::string& ditherer) {
  const std::array<double, 3>& voxel = profile.voxelSizeMm;
  return {{"purpose", "DMA calibration bars: measure each, then fit with rodfab calibrate, recording its vero_fraction "
                      "and ditherer (the data's dither column)"},
          {"ditherer", ditherer},
          {"seed", r.seed},
          {"requested_size_mm", r.sizeMm},
          {"size_voxels", coord(layout.bar)},
          {"size_mm", barMm(layout, profile)},
          {"gap_mm", {layout.gapI * voxel[0], layout.gapJ * voxel[1]}},
          {"rows", layout.rows},
          {"per_row", layout.perRow},
          {"position_note", "min corner of each bar in the manifest frame's mm; voxel (i, j, k) spans [i, i + 1) x the voxel size"},
          {"bars", bars}};
}

void printCouponSummary(const CouponRequest& r, const printer_profiles::JobResult& job,
                        const printer_profiles::Profile& profile, const slicer::CouponLayout& layout, const nlohmann::json& bars,
                        const slicer::StageSeconds& seconds, double total) {
  const std::string dither = bars.empty() ? std::string() : bars[0]["ditherer"].get<std::string>();
  if (r.job.json) {
    nlohmann::json j = jobJson(job, profile);
    j["ditherer"] = dither;
    j["seed"] = r.seed;
    j["size_mm"] = barMm(layout, profile);
    j["size_voxels"] = coord(layout.bar);
    j["rows"] = layout.rows;
    j["per_row"] = layout.perRow;
    j["bars"] = bars;
    j["seconds"] = {{"bands", seconds.wall},
                    {"total", total},
                    {"busy", {{"bars", seconds.source}, {"dither", seconds.dither}, {"emit", seconds.emit}}},
                    {"cpu_bands", seconds.cpu},
                    {"cpu", {{"bars", seconds.sourceCpu}, {"dither", seconds.ditherCpu}, {"emit", seconds.emitCpu}}}};
    std::cout << j.dump(2) << '\n';
    return;
  }
  printCouponLines(r, job, profile, layout, bars);
  std::printf("time:        %.2f s bands and job, %.2f s total (wall); busy %.2f s bars, %.2f s dither, %.2f s emit (overlapping); "
              "%.2f s CPU in the bands\n",
              seconds.wall, total, seconds.source, seconds.dither, seconds.emit, seconds.cpu);
  std::printf("next:        measure the bars, put each one's fraction and '%s' (dither column) in the DMA data, rodfab calibrate\n",
              dither.c_str());
}

std::optional<slicer::CouponLayout> layOutCoupons(const CouponRequest& r, const printer_profiles::Profile& profile, int& exitCode) {
  slicer::CouponVoxels voxels;
  try {
    voxels = slicer::couponVoxels(profile, r.sizeMm, r.gapMm);
  } catch (const std::invalid_argument& e) {
    return exitCode = usageError("coupons", e.what()), std::nullopt;
  } catch (const std::runtime_error& e) {
    std::cerr << "rodfab coupons: " << e.what() << "\nno job was written\n";
    return exitCode = kFailed, std::nullopt;
  }
  slicer::CouponLayout layout = slicer::planCouponLayout(profile, r.fractions.size(), voxels);
  try {
    printer_profiles::planJob(profile, layout.bounds);
  } catch (const printer_profiles::TrayFitError& e) {
    std::cerr << "rodfab coupons: " << r.fractions.size() << " bar(s) of " << barText(layout, profile) << " with "
              << formatNumber(r.gapMm) << " mm gaps, " << layout.rows << " row(s) of up to " << layout.perRow << ": "
              << e.what() << "\nno job was written\n";
    return exitCode = kFailed, std::nullopt;
  }
  return layout;
}

}  // namespace rodfab::cli
