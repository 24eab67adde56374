// What rodfab voxelize reports: warnings for rods the grid misses or barely holds, and the summary of
// the grid (text lines, or JSON with every rod's voxel count).
#pragma once

#include "geometry/rod.hpp"
#include "voxel/grid_statistics.hpp"
#include "voxel/printer_grid.hpp"

#include <cstddef>
#include <string>

namespace rodfab::cli {

// Warns on stderr ("rodfab voxelize: warning: ...") of every rod that holds voxels but is thin for
// the grid (voxel::findThinRods), then of every rod that holds no voxel centre. Returns how many
// rods hold none. `voxelsPerRod` is the rasterization's count per rod of `design`.
std::size_t warnThinAndEmptyRods(const geometry::RodStructure& design, const voxel::PrinterGrid& grid,
                                 const std::vector<std::uint64_t>& voxelsPerRod);

// A finished voxelization.
struct VoxelizeSummary {
  const std::string& file;         // the design, as given
  const std::string& output;       // the grid file written
  const std::string& profileName;  // "NAME (MODE)", or "(--voxel-size)"
  const geometry::RodStructure& design;
  const voxel::PrinterGrid& grid;
  const voxel::GridStatistics& s;
  std::size_t rodsWithoutVoxels;
  double seconds;  // wall time of the rasterization
};

// The summary on stdout: JSON (voxel size, envelope, origin, counts, moduli, bounds, every rod's
// voxels, time) or the text lines.
void printVoxelizeJson(const VoxelizeSummary& summary);
void printVoxelizeLines(const VoxelizeSummary& summary);

}  // namespace rodfab::cli
