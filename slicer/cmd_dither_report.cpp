// rodfab dither-report: every ditherer's quality (bias, low-pass error, clustering, runs, speed) on
// uniform blocks and a thin rod made at the profile's voxel (materials/dither_quality.hpp).
#include "common/memory_budget.hpp"
#include "common/stopwatch.hpp"
#include "materials/materials.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"
#include "slicer/profile_option.hpp"
#include "slicer/value_parsers.hpp"

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

// Block sides beyond this are not a dither measurement any more (and would leave OpenVDB's index range).
constexpr int kMaxBlockSide = 1 << 16;
// More uniform blocks than this are not a report any more (the memory estimate bounds them too).
constexpr std::size_t kMaxBlocks = 1000;

// Memory for the regions (sparse float grids, ~4.2 bytes a voxel, all held at once) and for measuring
// one of them (dense arrays over its box, ~56 bytes a voxel: materials/dither_quality.cpp).
std::uint64_t regionBytes(const openvdb::Coord& block, std::size_t blocks, double rodDiameterMm, double rodLengthMm,
                          const openvdb::Vec3d& v) {
  const double blockVoxels = double(block.x()) * block.y() * block.z();
  const double rodBox = (rodDiameterMm / v.x() + 2) * (rodDiameterMm / v.y() + 2) * (rodLengthMm / v.z() + 2);
  const double bytes = 4.2 * (blockVoxels * double(blocks) + rodBox) + 56.0 * std::max(blockVoxels, rodBox);
  return bytes > 1.8e19 ? std::uint64_t(1.8e19) : static_cast<std::uint64_t>(bytes);
}

int usageError(const std::string& what) { return cli::usageError("dither-report", what); }


// --dither: one ditherer's name (canonical: "random" is "white") or all of them; nullopt if unknown.
std::optional<std::vector<std::string>> ditherMethods(const std::string& chosen) {
  if (chosen == "all") return materials::ditherMethodNames();
  const std::string name = materials::canonicalDitherName(chosen);
  for (const std::string& n : materials::ditherMethodNames())
    if (n == name) return std::vector<std::string>{name};
  return std::nullopt;
}

void addDitherReportOptions(po::options_description& options) {
  options.add_options()
      ("dither", po::value<std::string>()->default_value("all"), "white, blue, error-diffusion or all")
      ("seed", po::value<Seed>()->default_value(Seed{1}), "dithering seed")
      ("block", po::value<std::string>()->default_value("128x64x180"), "uniform block size XxYxZ in voxels")
      ("fractions", po::value<std::string>()->default_value("0.1,0.2,...,0.9"),
       "Vero fractions of the uniform blocks, comma-separated; A,B,...,Z continues the step B - A up to Z")
      ("rod-diameter", po::value<double>()->default_value(1.0), "rod diameter in mm")
      ("rod-length", po::value<double>()->default_value(10.0), "rod length in mm")
      ("rod-axis", po::value<char>()->default_value('x'), "rod direction: x, y or z")
      ("rod-fraction", po::value<float>()->default_value(0.3f), "Vero fraction of the rod")
      ("mask", po::value<std::string>(), "blue-noise mask file (default: the bundled one)")
      ("json", "print the report as JSON on stdout");
  addProfileOptions(options);
}

struct ReportRequest {
  std::vector<std::string> methods;
  std::vector<float> fractions;
  openvdb::Coord block;
  char axis = 'x';
  double diameterMm = 0.0, lengthMm = 0.0;
  float rodFraction = 0.0f;
  bool json = false;
};

// The request from a parsed command line; nullopt after a usage error.
std::optional<ReportRequest> readRequest(const po::variables_map& vm) {
  ReportRequest r;
  const std::string chosen = vm.count("ditherer") ? vm["ditherer"].as<std::string>() : vm["dither"].as<std::string>();
  const std::optional<std::vector<std::string>> methods = ditherMethods(chosen);
  if (!methods) return usageError("--dither: unknown ditherer '" + chosen + "', expected white, blue, error-diffusion or all"), std::nullopt;
  r.methods = *methods;
  try {
    for (double f : parseFractionList("--fractions", vm["fractions"].as<std::string>(), kMaxBlocks))
      r.fractions.push_back(static_cast<float>(f));
    const std::array<int, 3> sides = parseSizeVoxels("--block", vm["block"].as<std::string>(), kMaxBlockSide);
    r.block = openvdb::Coord(sides[0], sides[1], sides[2]);
  } catch (const BadValue& e) {
    return usageError(e.what()), std::nullopt;
  }
  r.axis = vm["rod-axis"].as<char>();
  if (r.axis < 'x' || r.axis > 'z') return usageError("--rod-axis: expected x, y or z"), std::nullopt;
  const std::optional<double> diameter = realOption("dither-report", vm, "rod-diameter", 1e-3, 1e3, "mm");
  const std::optional<double> length = realOption("dither-report", vm, "rod-length", 1e-3, 1e4, "mm");
  if (!diameter || !length) return std::nullopt;
  r.diameterMm = *diameter, r.lengthMm = *length;
  r.rodFraction = vm["rod-fraction"].as<float>();
  if (!(r.rodFraction >= 0.0f && r.rodFraction <= 1.0f)) return usageError("--rod-fraction: expected a number in [0, 1]"), std::nullopt;
  r.json = vm.count("json") > 0;
  return r;
}

std::vector<Region> makeRegions(const ReportRequest& r, const openvdb::Vec3d& voxel) {
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

// Dithers every region with every method, measures it and prints a row (or the JSON array at the end).
void report(const ReportRequest& r, const std::vector<Region>& regions, const materials::DitherOptions& ditherOptions) {
  nlohmann::json rows = nlohmann::json::array();
  if (!r.json)
    std::printf("%-16s %-12s %8s %9s %10s %10s %8s %17s %9s\n", "ditherer", "region", "voxels", "bias",
                "rms@100um", "rms@250um", "cluster", "runs x/y/z", "Mvox/s");
  for (const std::string& method : r.methods) {
    for (const Region& region : regions) {
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

}  // namespace

int runDitherReport(const std::vector<std::string>& args) {
  po::options_description options("options"), hidden;
  addDitherReportOptions(options);
  hidden.add_options()("ditherer", po::value<std::string>(), "the old spelling of --dither");
  po::variables_map vm;
  if (auto code = parseOptions("dither-report", "[options]", options, {}, args, vm, &hidden)) return *code;
  const std::optional<ReportRequest> request = readRequest(vm);
  if (!request) return kUsage;
  commandLineAccepted();
  // The regions are made at the printer's voxel: the profile's, the only source of it.
  const std::optional<printer_profiles::Profile> profile = profileFromOptions(vm, "no report was made");
  if (!profile) return kFailed;
  const openvdb::Vec3d voxel(profile->voxelSizeMm[0], profile->voxelSizeMm[1], profile->voxelSizeMm[2]);
  common::requireMemory(regionBytes(request->block, request->fractions.size(), request->diameterMm, request->lengthMm, voxel),
                        "dither-report's " + std::to_string(request->fractions.size()) + " blocks and rod",
                        "use a smaller --block, fewer --fractions or a shorter --rod-length");
  materials::DitherOptions ditherOptions;
  ditherOptions.seed = vm["seed"].as<Seed>().value;
  if (vm.count("mask")) {
    try {
      ditherOptions.mask = std::make_shared<const materials::BlueNoiseMask>(materials::BlueNoiseMask::load(vm["mask"].as<std::string>()));
    } catch (const std::exception& e) {
      std::cerr << e.what() << '\n';
      return kFailed;
    }
  }
  report(*request, makeRegions(*request, voxel), ditherOptions);
  return kOk;
}

}  // namespace rodfab::cli
