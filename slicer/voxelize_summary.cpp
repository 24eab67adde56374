#include "slicer/voxelize_summary.hpp"

#include "voxel/diagnostics.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <iostream>

namespace rodfab::cli {

std::size_t warnThinAndEmptyRods(const geometry::RodStructure& design, const voxel::PrinterGrid& grid,
                                 const std::vector<std::uint64_t>& voxelsPerRod) {
  // A rod thinner than a voxel can fall between voxel centres: the technician must hear of it.
  std::vector<std::size_t> empty;
  for (std::size_t r = 0; r < voxelsPerRod.size(); ++r)
    if (voxelsPerRod[r] == 0) empty.push_back(r);
  for (const voxel::ThinRod& thin : voxel::findThinRods(design, grid, voxelsPerRod))
    if (voxelsPerRod[thin.rod] > 0) std::cerr << "rodfab voxelize: warning: " << thin.reason << '\n';
  for (std::size_t r : empty)
    std::cerr << "rodfab voxelize: warning: rod " << r << " ('" << design.rods[r].name()
              << "') holds no voxel centre; it is thinner than the voxel or hidden inside other rods\n";
  return empty.size();
}

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

}  // namespace rodfab::cli
