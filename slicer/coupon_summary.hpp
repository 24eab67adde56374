// What `rodfab coupons` asked for and what it reports: the request from the command line, the
// manifest's metadata.coupons block and the summary (text or --json) printed after the job.
#pragma once

#include "printer_profiles/job_writer.hpp"
#include "slicer/coupon_layout.hpp"
#include "slicer/job_options.hpp"

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rodfab::cli {

struct CouponRequest {
  JobCommandOptions job;
  std::vector<double> fractions;     // one bar each, in [0, 1]
  std::array<double, 3> sizeMm{};    // asked, before rounding to voxels
  double gapMm = 0.0;
  std::uint64_t seed = 0;
};

// Voxel (i, j, k) spans [i, i + 1) x the voxel size in mm: the layout starts at the frame's origin.
openvdb::Vec3d couponOriginMm(const printer_profiles::Profile& profile);

// "30.014 x 5.080 x 1.500 mm": a bar as laid out, in whole voxels.
std::string barText(const slicer::CouponLayout& layout, const printer_profiles::Profile& profile);

// The bars of `request` on the tray of `profile` (slicer::couponVoxels, planCouponLayout, then
// printer_profiles::planJob). On failure prints why to stderr and returns nullopt with `exitCode` set:
// kUsage for a bar or gap under one voxel (a usage error naming --size or --gap), kFailed with "no job
// was written" for bars that do not fit the tray (with the bar size, gaps and rows in the message).
std::optional<slicer::CouponLayout> layOutCoupons(const CouponRequest& request, const printer_profiles::Profile& profile,
                                                  int& exitCode);

// The job's spec: the bars' bounds, origin (couponOriginMm), ditherer, seed, output options and a
// report.html without calibration or clamping.
printer_profiles::JobSpec couponJobSpec(const CouponRequest& request, const printer_profiles::Profile& profile,
                                        const slicer::CouponLayout& layout, const std::string& ditherName);

// The manifest's metadata.coupons: purpose, ditherer, seed, sizes asked and made, gaps, rows and `bars`
// (slicer::couponBarsJson).
nlohmann::json couponsManifest(const CouponRequest& request, const slicer::CouponLayout& layout,
                               const printer_profiles::Profile& profile, const nlohmann::json& bars, const std::string& ditherer);

// The summary on stdout: JSON with --json, lines otherwise (one per bar and per material).
void printCouponSummary(const CouponRequest& request, const printer_profiles::JobResult& job,
                        const printer_profiles::Profile& profile, const slicer::CouponLayout& layout, const nlohmann::json& bars,
                        const slicer::StageSeconds& seconds, double totalSeconds);

}  // namespace rodfab::cli
