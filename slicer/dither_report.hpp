// What rodfab dither-report measures: uniform blocks and a thin rod made at the printer's voxel, each
// dithered by every chosen ditherer and measured (materials/dither_quality.hpp), printed as a table
// or as JSON.
#pragma once

#include "materials/ditherer.hpp"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rodfab::cli {

// The ditherers a --dither value names: one (canonical: "random" is "white") or, for "all", every
// one; nullopt when it names none.
std::optional<std::vector<std::string>> ditherMethods(const std::string& chosen);

struct DitherReportRequest {
  std::vector<std::string> methods;  // canonical ditherer names
  std::vector<float> fractions;      // Vero fraction of each uniform block, in [0, 1]
  openvdb::Coord block;              // a block's size in voxels
  char axis = 'x';                   // the rod's direction: 'x', 'y' or 'z'
  double diameterMm = 0.0, lengthMm = 0.0;
  float rodFraction = 0.0f;
  bool json = false;
};

// Memory (bytes) for the report at voxel size `voxelMm`: the regions (sparse float grids, ~4.2 bytes a
// voxel, all held at once) and the measurement of the largest of them (dense arrays over its box, ~56
// bytes a voxel: materials/dither_quality.cpp), saturated (common::saturatedBytes).
std::uint64_t ditherReportBytes(const DitherReportRequest& request, const openvdb::Vec3d& voxelMm);

// Makes the blocks and the rod at `voxelMm`, dithers each with every method (`options` give the seed
// and mask), measures it and prints a row on stdout, or with request.json a JSON array at the end.
// The speed column (Mvoxels/s) is wall time, the only figure that varies between runs.
void printDitherReport(const DitherReportRequest& request, const openvdb::Vec3d& voxelMm, const materials::DitherOptions& options);

}  // namespace rodfab::cli
