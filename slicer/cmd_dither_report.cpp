#include "materials/materials.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"
#include "slicer/profile_option.hpp"

#include "common/memory_budget.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <sstream>

namespace rodfab::cli {

namespace {

struct Region {
  std::string name;
  openvdb::FloatGrid::Ptr fraction;
};

// "0.1,0.5" -> {0.1, 0.5}; nullopt when a token is not a number in [0, 1].
std::optional<std::vector<float>> parseFractions(const std::string& text) {
  std::vector<float> out;
  std::stringstream in(text);
  std::string token;
  while (std::getline(in, token, ',')) {
    try {
      std::size_t used = 0;
      const float f = std::stof(token, &used);
      if (used != token.size() || !(f >= 0.0f && f <= 1.0f)) return std::nullopt;
      out.push_back(f);
    } catch (const std::exception&) {
      return std::nullopt;
    }
  }
  if (out.empty()) return std::nullopt;
  return out;
}

// Block sides beyond this are not a dither measurement any more (and would leave OpenVDB's index range).
constexpr int kMaxBlockSide = 1 << 16;

std::optional<openvdb::Coord> parseSize(const std::string& text) {
  int sides[3] = {0, 0, 0};
  const char* at = text.c_str();
  for (int a = 0; a < 3; ++a) {
    if (a > 0 && *at++ != 'x') return std::nullopt;
    if (*at < '0' || *at > '9') return std::nullopt;
    char* end = nullptr;
    errno = 0;
    const long side = std::strtol(at, &end, 10);
    if (errno == ERANGE || side < 1 || side > kMaxBlockSide) return std::nullopt;
    sides[a] = static_cast<int>(side);
    at = end;
  }
  if (*at != '\0') return std::nullopt;
  return openvdb::Coord(sides[0], sides[1], sides[2]);
}

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

}  // namespace

int runDitherReport(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("ditherer", po::value<std::string>()->default_value("all"), "white, blue, error-diffusion or all")
      ("seed", po::value<Seed>()->default_value(Seed{1}), "dithering seed")
      ("block", po::value<std::string>()->default_value("128x64x180"), "uniform block size in voxels, XxYxZ")
      ("fractions", po::value<std::string>()->default_value("0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9"),
       "Vero fractions of the uniform blocks, comma-separated")
      ("rod-diameter", po::value<double>()->default_value(1.0), "rod diameter in mm")
      ("rod-length", po::value<double>()->default_value(10.0), "rod length in mm")
      ("rod-axis", po::value<char>()->default_value('x'), "rod direction: x, y or z")
      ("rod-fraction", po::value<float>()->default_value(0.3f), "Vero fraction of the rod")
      ("mask", po::value<std::string>(), "blue-noise mask file (default: the bundled one)")
      ("json", "print the report as JSON on stdout");
  addProfileOptions(options);
  po::positional_options_description positional;
  po::variables_map vm;
  if (auto code = parseOptions("dither-report", "[options]", options, positional, args, vm)) return *code;

  std::vector<std::string> methods;
  const std::string chosen = vm["ditherer"].as<std::string>();
  if (chosen == "all") {
    methods = materials::ditherMethodNames();
  } else {
    bool known = false;
    for (const std::string& n : materials::ditherMethodNames()) known = known || n == chosen;
    if (!known) return usageError("unknown ditherer '" + chosen + "', expected white, blue, error-diffusion or all");
    methods = {chosen};
  }
  const auto fractions = parseFractions(vm["fractions"].as<std::string>());
  if (!fractions) return usageError("--fractions: expected comma-separated numbers in [0, 1]");
  const auto block = parseSize(vm["block"].as<std::string>());
  if (!block)
    return usageError("--block: expected XxYxZ voxel counts from 1 to " + std::to_string(kMaxBlockSide) + ", e.g. 128x64x180");
  const char axisName = vm["rod-axis"].as<char>();
  if (axisName < 'x' || axisName > 'z') return usageError("--rod-axis: expected x, y or z");
  const std::optional<double> diameterOption = realOption("dither-report", vm, "rod-diameter", 1e-3, 1e3, "mm");
  const std::optional<double> lengthOption = realOption("dither-report", vm, "rod-length", 1e-3, 1e4, "mm");
  if (!diameterOption || !lengthOption) return kUsage;
  const double diameter = *diameterOption, length = *lengthOption;
  const float rodFractionValue = vm["rod-fraction"].as<float>();
  if (!(rodFractionValue >= 0.0f && rodFractionValue <= 1.0f)) return usageError("--rod-fraction: expected a number in [0, 1]");
  commandLineAccepted();
  // The regions are made at the printer's voxel: the profile's, the only source of it.
  const std::optional<printer_profiles::Profile> profile = profileFromOptions(vm, "no report was made");
  if (!profile) return kFailed;
  const openvdb::Vec3d voxel(profile->voxelSizeMm[0], profile->voxelSizeMm[1], profile->voxelSizeMm[2]);
  common::requireMemory(regionBytes(*block, fractions->size(), diameter, length, voxel),
                        "dither-report's " + std::to_string(fractions->size()) + " blocks and rod",
                        "use a smaller --block, fewer --fractions or a shorter --rod-length");
  const float rodFraction = rodFractionValue;
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

  std::vector<Region> regions;
  for (float f : *fractions) {
    char name[64];
    std::snprintf(name, sizeof name, "block %.2f", f);
    regions.push_back({name, materials::makeUniformBlock(*block, f, voxel)});
  }
  char rodName[64];
  std::snprintf(rodName, sizeof rodName, "rod %c %.2f", axisName, rodFraction);
  regions.push_back({rodName, materials::makeRod(diameter, length, axisName - 'x', rodFraction, voxel)});

  nlohmann::json report = nlohmann::json::array();
  const bool json = vm.count("json") > 0;
  if (!json)
    std::printf("%-16s %-12s %8s %9s %10s %10s %8s %17s %9s\n", "ditherer", "region", "voxels", "bias",
                "rms@100um", "rms@250um", "cluster", "runs x/y/z", "Mvox/s");
  for (const std::string& method : methods) {
    for (const Region& region : regions) {
      const auto ditherer = materials::makeDitherer(method, ditherOptions);
      const auto start = std::chrono::steady_clock::now();
      const openvdb::BoolGrid::Ptr material = ditherer->dither(*region.fraction);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      const materials::DitherQuality q = materials::measureDitherQuality(*region.fraction, *material);
      const double rate = seconds > 0 ? static_cast<double>(q.voxels) / seconds / 1e6 : 0.0;
      if (json) {
        report.push_back({{"ditherer", method},
                          {"region", region.name},
                          {"voxels", q.voxels},
                          {"target_mean", q.targetMean},
                          {"achieved_mean", q.achievedMean},
                          {"mean_bias", q.meanBias},
                          {"lowpass_rms_100um", q.lowPassRms100um},
                          {"lowpass_rms_250um", q.lowPassRms250um},
                          {"largest_vero_cluster_share", q.largestVeroClusterShare},
                          {"mean_run_length_voxels", q.meanRunLength},
                          {"mvoxels_per_second", rate}});
      } else {
        std::printf("%-16s %-12s %8zu %+9.5f %10.5f %10.5f %8.3f %5.2f/%5.2f/%5.2f %9.1f\n", method.c_str(),
                    region.name.c_str(), q.voxels, q.meanBias, q.lowPassRms100um, q.lowPassRms250um,
                    q.largestVeroClusterShare, q.meanRunLength[0], q.meanRunLength[1], q.meanRunLength[2], rate);
      }
    }
  }
  if (json) std::cout << report.dump(2) << '\n';
  return kOk;
}

}  // namespace rodfab::cli
