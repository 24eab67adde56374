// A tileable 3D blue-noise threshold mask: a permutation of ranks 0 .. N-1 over an nx x ny x nz tile,
// made by the void-and-cluster method (Ulichney 1993) with a Gaussian energy filter that is isotropic
// in millimetres for an anisotropic voxel. Ordered dithering compares a fraction with (rank + 0.5) / N.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

namespace rodfab::materials {

// Everything that determines a mask: the same parameters give the same ranks, bit for bit, on any
// machine (the generator runs on integer energies, so no floating-point drift or reordering matters).
// The voxel size has no default: the filter is isotropic in millimetres for that voxel only, so a mask
// belongs to one printer voxel. That voxel is a property of the mask (saved in its file as
// voxel_size_nm, parameters() after load), not of this code; the printer's voxel comes from its profile.
struct BlueNoiseParameters {
  // The defaults are the bundled mask's (bundledMask() adds its voxel), written here only.
  std::array<int, 3> size{64, 32, 90};     // tile in voxels (x, y, z)
  std::array<double, 3> voxelSizeMm{};     // the voxel (x, y, z in mm) the filter is isotropic for; > 0
  double sigmaMm = 0.072;                  // energy filter, in mm along every axis
  double initialDensity = 0.1;             // share of ones in the random starting pattern
  std::uint64_t seed = 1;

  // The parameters of the bundled mask file (materials/README.md): the defaults above for the Connex3
  // voxel (600 x 300 dpi, 30 um layers: the voxel the file records), a tile of about 2.7 mm each way.
  // Regenerating with these reproduces the file byte for byte.
  static BlueNoiseParameters bundledMask();
};

class BlueNoiseMask {
public:
  // Generates the mask. Cost is O(N * filter support); 184,320 cells take a few seconds (one thread).
  // Throws std::invalid_argument for sizes < 2 or > 1024 per axis, sigma <= 0 or density outside (0, 0.5].
  static BlueNoiseMask generate(const BlueNoiseParameters& parameters);

  // Reads a mask file (format in materials/README.md) and checks it is a complete permutation;
  // throws std::runtime_error naming the file and the field that is wrong.
  static BlueNoiseMask load(const std::filesystem::path& file);
  // The mask shipped in materials/ (generated from BlueNoiseParameters::bundledMask()), read once per
  // process and shared. It is applied by voxel index on any printer grid: every tile still holds each
  // rank once, so a fraction f turns on round(f * N) cells a tile on any voxel; only its blue-noise
  // spectrum is isotropic in mm for the voxel it records (voxelSizeMm()) and stretched on another. Found in masks/ of rodfab's data folder (common/data_dir.hpp; installed from
  // materials/); bundledPath() throws common::DataDirError when it is missing.
  static std::shared_ptr<const BlueNoiseMask> bundled();
  static std::filesystem::path bundledPath();

  // Writes the mask file; throws std::runtime_error on I/O errors.
  void save(const std::filesystem::path& file) const;

  const BlueNoiseParameters& parameters() const { return parameters_; }
  const std::array<int, 3>& size() const { return parameters_.size; }
  // The voxel (x, y, z in mm) the mask was made for, as its file records it.
  const std::array<double, 3>& voxelSizeMm() const { return parameters_.voxelSizeMm; }
  std::size_t cellCount() const { return ranks_.size(); }
  // Ranks in x-fastest order: cell (i, j, k) of the tile is at (k * ny + j) * nx + i.
  const std::vector<std::uint32_t>& ranks() const { return ranks_; }
  std::uint32_t rank(int i, int j, int k) const { return ranks_[index(i, j, k)]; }
  // Thresholds (rank + 0.5) / N in the same order: a fraction f turns exactly round(f * N) cells of a
  // tile on, so a whole tile has no bias, 0 gives none and 1 gives all.
  const std::vector<float>& thresholds() const { return thresholds_; }

  std::size_t index(int i, int j, int k) const {
    return (static_cast<std::size_t>(k) * parameters_.size[1] + j) * parameters_.size[0] + i;
  }

private:
  BlueNoiseMask(BlueNoiseParameters parameters, std::vector<std::uint32_t> ranks);

  BlueNoiseParameters parameters_;
  std::vector<std::uint32_t> ranks_;
  std::vector<float> thresholds_;
};

}  // namespace rodfab::materials
