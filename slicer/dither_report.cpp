#include "slicer/dither_report.hpp"

#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "common/stopwatch.hpp"
#include "materials/materials.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>

namespace rodfab::cli {

namespace {

struct Region {
  std::string name;
  openvdb::FloatGrid::Ptr fraction;
};

std::vector<Region> makeRegions(const DitherReportRequest& r, const openvdb::Vec3d& voxel) {
  std::vector<Region> regions;
  for (float f : r.fractions) {
    char name[64];
    std::snprintf(name, sizeof name, "block %.2f", f);
    regions.push_back({name, materials::makeUniformBlock(r.block, f, voxel)});
  }
  char rodName[64];
  std::snprintf(rodName, sizeof rodName, "rod %c %.2f", r.axis, r.rodFraction);
  regions.push_back({rodName, materials::makeRod(r.diameterMm, r.lengthMm, r.axis - 'x', r.rodFraction, voxel)});
  return regions;
}

nlohmann::json qualityJson(const std::string& method, const Region& region, const materials::DitherQuality& q, double rate) {
  return {{"ditherer", method},
          {"region", region.name},
          {"voxels", q.voxels},
          {"target_mean", q.targetMean},
          {"achieved_mean", q.achievedMean},
          {"mean_bias", q.meanBias},
          {"lowpass_rms_100um", q.lowPassRms100um},
          {"lowpass_rms_250um", q.lowPassRms250um},
          {"largest_vero_cluster_share", q.largestVeroClusterShare},
          {"mean_run_length_voxels", q.meanRunLength},
          {"mvoxels_per_second", rate}};
}

}  // namespace

std::optional<std::vector<std::string>> ditherMethods(const std::string& chosen) {
  if (chosen == "all") return materials::ditherMethodNames();
  const std::string name = materials::canonicalDitherName(chosen);
  for (const std::string& n : materials::ditherMethodNames())
    if (n == name) return std::vector<std::string>{name};
  return std::nullopt;
}

std::uint64_t ditherReportBytes(const DitherReportRequest& r, const openvdb::Vec3d& v) {
  const double blockVoxels = double(r.block.x()) * r.block.y() * r.block.z();
  const double rodBox = (r.diameterMm / v.x() + 2) * (r.diameterMm / v.y() + 2) * (r.lengthMm / v.z() + 2);
  const double bytes = 4.2 * (blockVoxels * double(r.fractions.size()) + rodBox) + 56.0 * std::max(blockVoxels, rodBox);
  return common::saturatedBytes(bytes);
}

void printDitherReport(const DitherReportRequest& r, const openvdb::Vec3d& voxelMm, const materials::DitherOptions& ditherOptions) {
  const std::vector<Region> regions = makeRegions(r, voxelMm);
  nlohmann::json rows = nlohmann::json::array();
  if (!r.json)
    std::printf("%-16s %-12s %8s %9s %10s %10s %8s %17s %9s\n", "ditherer", "region", "voxels", "bias",
                "rms@100um", "rms@250um", "cluster", "runs x/y/z", "Mvox/s");
  for (const std::string& method : r.methods) {
    for (const Region& region : regions) {
      common::throwIfInterrupted();  // measuring a region reads all of it
      const auto ditherer = materials::makeDitherer(method, ditherOptions);
      const auto start = std::chrono::steady_clock::now();
      const openvdb::BoolGrid::Ptr material = ditherer->dither(*region.fraction);
      const double seconds = common::secondsSince(start);
      const materials::DitherQuality q = materials::measureDitherQuality(*region.fraction, *material);
      const double rate = seconds > 0 ? static_cast<double>(q.voxels) / seconds / 1e6 : 0.0;
      if (r.json) rows.push_back(qualityJson(method, region, q, rate));
      else
        std::printf("%-16s %-12s %8zu %+9.5f %10.5f %10.5f %8.3f %5.2f/%5.2f/%5.2f %9.1f\n", method.c_str(),
                    region.name.c_str(), q.voxels, q.meanBias, q.lowPassRms100um, q.lowPassRms250um,
                    q.largestVeroClusterShare, q.meanRunLength[0], q.meanRunLength[1], q.meanRunLength[2], rate);
    }
  }
  if (r.json) std::cout << rows.dump(2) << '\n';
}

}  // namespace rodfab::cli
