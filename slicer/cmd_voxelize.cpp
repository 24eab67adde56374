#include "geometry/geometry.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"
#include "slicer/profile_option.hpp"

#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "voxel/diagnostics.hpp"
#include "voxel/memory_estimate.hpp"
#include "voxel/voxel.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>
#include <sstream>

namespace rodfab::cli {

namespace {

// "0.0423,0.0846,0.030" -> mm per axis; nullopt when it is not three positive numbers.
std::optional<openvdb::Vec3d> parseVoxelSize(const std::string& text) {
  openvdb::Vec3d size;
  std::istringstream in(text);
  for (int a = 0; a < 3; ++a) {
    if (a > 0 && in.get() != ',') return std::nullopt;
    // From 1 um (finer than any printer) to 10 mm (coarser than any rod worth printing).
    if (!(in >> size[a]) || !(size[a] >= 1e-3 && size[a] <= 10.0)) return std::nullopt;
  }
  if (in.peek() != std::char_traits<char>::eof()) return std::nullopt;
  return size;
}

// What voxelize made, for its summary.
struct VoxelizeSummary {
  const std::string& file;
  const std::string& output;
  const std::string& profileName;
  const geometry::RodStructure& design;
  const voxel::PrinterGrid& grid;
  const voxel::GridStatistics& s;
  std::size_t rodsWithoutVoxels;
  double seconds;
};

void printVoxelizeJson(const VoxelizeSummary& v) {
  const auto& [file, output, profileName, design, grid, s, rodsWithoutVoxels, seconds] = v;
  nlohmann::json perRod = nlohmann::json::array();
  for (std::size_t r = 0; r < s.voxelsPerRod.size(); ++r)
    perRod.push_back({{"name", design.rods[r].name()}, {"voxels", s.voxelsPerRod[r]}});
  const auto& b = s.boundsVoxels;
  nlohmann::json j{
      {"design", file},
      {"output", output},
      {"profile", profileName},
      {"voxel_size_mm", {grid.voxelSize.x(), grid.voxelSize.y(), grid.voxelSize.z()}},
      {"envelope_voxels", {grid.dims.x(), grid.dims.y(), grid.dims.z()}},
      {"origin_mm", {grid.origin.x(), grid.origin.y(), grid.origin.z()}},
      {"active_voxels", s.activeVoxels},
      {"occupied_volume_mm3", s.occupiedVolumeMm3},
      {"modulus_mpa", {{"min", s.modulusMin}, {"mean", s.modulusMean}, {"max", s.modulusMax}}},
      {"bounds_voxels", s.activeVoxels ? nlohmann::json{{"min", {b.min().x(), b.min().y(), b.min().z()}},
                                                        {"max", {b.max().x(), b.max().y(), b.max().z()}}}
                                       : nlohmann::json(nullptr)},
      {"bounds_mm", {{"min", {s.boundsMinMm.x(), s.boundsMinMm.y(), s.boundsMinMm.z()}},
                     {"max", {s.boundsMaxMm.x(), s.boundsMaxMm.y(), s.boundsMaxMm.z()}}}},
      {"rods", perRod},
      {"rods_without_voxels", rodsWithoutVoxels},
      {"seconds", seconds}};
  std::cout << j.dump(2) << '\n';
}

void printVoxelizeLines(const VoxelizeSummary& v) {
  const auto& [file, output, profileName, design, grid, s, rodsWithoutVoxels, seconds] = v;
  const double envelope = double(grid.voxelCount());
  const auto& b = s.boundsVoxels;
  std::printf("design:          %s (%zu rods)\n", file.c_str(), design.rods.size());
  std::printf("profile:         %s\n", profileName.c_str());
  std::printf("voxel:           %.4f x %.4f x %.4f mm\n", grid.voxelSize.x(), grid.voxelSize.y(), grid.voxelSize.z());
  std::printf("envelope:        %d x %d x %d voxels (%.3g voxels)\n", grid.dims.x(), grid.dims.y(), grid.dims.z(), envelope);
  std::printf("active voxels:   %llu (%.3f %% of the envelope)\n", static_cast<unsigned long long>(s.activeVoxels),
              envelope > 0 ? 100.0 * double(s.activeVoxels) / envelope : 0.0);
  std::printf("occupied volume: %.3f mm^3\n", s.occupiedVolumeMm3);
  if (s.activeVoxels > 0) {
    std::printf("modulus:         %.3f / %.3f / %.3f MPa (min / mean / max)\n", s.modulusMin, s.modulusMean, s.modulusMax);
    std::printf("bounds:          voxels (%d, %d, %d) .. (%d, %d, %d)\n", b.min().x(), b.min().y(), b.min().z(), b.max().x(),
                b.max().y(), b.max().z());
    std::printf("                 mm (%.3f, %.3f, %.3f) .. (%.3f, %.3f, %.3f)\n", s.boundsMinMm.x(), s.boundsMinMm.y(),
                s.boundsMinMm.z(), s.boundsMaxMm.x(), s.boundsMaxMm.y(), s.boundsMaxMm.z());
  }
  std::uint64_t fewest = s.voxelsPerRod.empty() ? 0 : s.voxelsPerRod[0], most = fewest;
  for (std::uint64_t n : s.voxelsPerRod) fewest = std::min(fewest, n), most = std::max(most, n);
  std::printf("voxels per rod:  %llu .. %llu (--json lists every rod)\n", static_cast<unsigned long long>(fewest),
              static_cast<unsigned long long>(most));
  std::printf("time:            %.3f s (%.1f M active voxels/s)\n", seconds,
              seconds > 0 ? double(s.activeVoxels) / seconds * 1e-6 : 0.0);
  std::printf("written:         %s\n", output.c_str());
}

}  // namespace

int runVoxelize(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("design", po::value<std::string>()->required(), "design file (rodfab.design/1 JSON)")
      ("output,o", po::value<std::string>()->required(), "grid file to write (.vdb, grid \"modulus_mpa\")")
      ("voxel-size", po::value<std::string>(),
       "voxel size X,Y,Z in mm (z = build direction) instead of a printer profile's voxel")
      ("json", "print the statistics as JSON on stdout");
  addThreadsOption(options, "the grid is the same for any count");
  addProfileOptions(options);
  po::positional_options_description positional;
  positional.add("design", 1);
  po::variables_map vm;
  const char* synopsis =
      "DESIGN.json --output GRID.vdb [--profile NAME|FILE] [--print-mode MODE] [--voxel-size X,Y,Z] [--threads N] [--json]";
  if (auto code = parseOptions("voxelize", synopsis, options, positional, args, vm)) return *code;

  std::optional<openvdb::Vec3d> voxelSize;
  if (vm.count("voxel-size")) {
    if (!vm["profile"].defaulted() || vm.count("print-mode"))
      return usageError("voxelize", "--voxel-size replaces the profile's voxel: give it or --profile/--print-mode, not both");
    voxelSize = parseVoxelSize(vm["voxel-size"].as<std::string>());
    if (!voxelSize)
      return usageError("voxelize", "--voxel-size: expected three sizes from 0.001 to 10 mm as X,Y,Z (e.g. 0.0423,0.0846,0.030), got '" +
                                        vm["voxel-size"].as<std::string>() + "'");
  }
  const std::optional<int> threadsOption = threadCount("voxelize", vm);
  if (!threadsOption) return kUsage;
  const int threads = *threadsOption;
  const std::string file = vm["design"].as<std::string>(), output = vm["output"].as<std::string>();
  commandLineAccepted();
  const ThreadLimit limit(threads);
  std::string profileName = "(--voxel-size)";
  if (!voxelSize) {
    const std::optional<printer_profiles::Profile> profile = profileFromOptions(vm, "nothing was written");
    if (!profile) return kFailed;
    voxelSize = openvdb::Vec3d(profile->voxelSizeMm[0], profile->voxelSizeMm[1], profile->voxelSizeMm[2]);
    profileName = profile->name + (profile->printMode.empty() ? "" : " (" + profile->printMode + ")");
  }
  const std::optional<geometry::RodStructure> read = readDesignOrReport(file, "nothing was written");
  if (!read) return kFailed;
  const geometry::RodStructure& design = *read;
  // An existing grid is replaced only when rodfab wrote it.
  if (!outputAllowed(output, {file}, {"grid file", true, "", [](const std::filesystem::path& p) {
                                        return voxel::isGridFile(p.string());
                                      }}))
    return kFailed;

  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, *voxelSize);
  // The whole grid is held in memory (slice streams bands instead): refuse before the first voxel.
  common::requireMemory(voxel::estimateRasterizationBytes(design, grid), "voxelizing " + file + " into one grid in memory",
                        "use a coarser --voxel-size, or slice the design (`rodfab slice` streams it in bands)");
  const voxel::Rasterization ras = voxel::rasterize(design, grid, {threads, common::interruptRequested});
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  const voxel::GridStatistics s = voxel::computeStatistics(*ras.grid, grid, ras.voxelsPerRod);

  openvdb::MetaMap metadata;
  metadata.insertMeta("rodfab_design", openvdb::StringMetadata(file));
  metadata.insertMeta("rodfab_voxel_size_mm", openvdb::Vec3DMetadata(grid.voxelSize));
  voxel::writeGridFile(output, *ras.grid, metadata);

  // A rod thinner than a voxel can fall between voxel centres: the technician must hear of it.
  std::vector<std::size_t> empty;
  for (std::size_t r = 0; r < s.voxelsPerRod.size(); ++r)
    if (s.voxelsPerRod[r] == 0) empty.push_back(r);
  for (const voxel::ThinRod& thin : voxel::findThinRods(design, grid, s.voxelsPerRod))
    if (s.voxelsPerRod[thin.rod] > 0) std::cerr << "rodfab voxelize: warning: " << thin.reason << '\n';
  for (std::size_t r : empty)
    std::cerr << "rodfab voxelize: warning: rod " << r << " ('" << design.rods[r].name()
              << "') holds no voxel centre; it is thinner than the voxel or hidden inside other rods\n";

  const VoxelizeSummary summary{file, output, profileName, design, grid, s, empty.size(), seconds};
  if (vm.count("json")) printVoxelizeJson(summary);
  else printVoxelizeLines(summary);
  return kOk;
}

}  // namespace rodfab::cli
