// Dithering: one material per voxel from a Vero fraction per voxel.
//
// Grid conventions shared along the chain:
//   input  openvdb::FloatGrid "vero_fraction": active voxels = inside the part, value = share of
//          VeroWhitePlus wanted there, in [0, 1]; index (i, j, k) = printer voxel, k = layer (build z).
//   output openvdb::BoolGrid "material": exactly the same active voxels, the fraction grid's transform;
//          true = VeroWhitePlus (rigid model material), false = TangoBlackPlus (rubbery).
// Fractions exactly 0 and 1 always give Tango and Vero. A value outside [0, 1] (or NaN) is an error.
//
// Every ditherer is deterministic for a seed and gives identical grids for any thread count and for any
// split of the layers into bands: dithering layers [k0, k1) returns exactly those layers of a
// whole-grid run, so a slicer can stream band after band.
#pragma once

#include "materials/blue_noise_mask.hpp"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rodfab::materials {

class FractionMap;     // fraction_map.hpp
struct MappingStats;   // fraction_map.hpp

inline constexpr bool kVero = true;    // VeroWhitePlus
inline constexpr bool kTango = false;  // TangoBlackPlus
inline constexpr const char* kFractionGridName = "vero_fraction";
inline constexpr const char* kMaterialGridName = "material";

struct DitherOptions {
  DitherOptions(std::uint64_t seedValue = 0, std::shared_ptr<const BlueNoiseMask> maskToUse = {})
      : seed(seedValue), mask(std::move(maskToUse)) {}
  std::uint64_t seed = 0;
  // Threshold mask of the "blue" ditherer; null = the bundled mask (BlueNoiseMask::bundled()).
  std::shared_ptr<const BlueNoiseMask> mask;
  // Cancellation: when set, every ditherer calls it from its worker threads (white and blue: before
  // each 8^3 leaf; error diffusion: before each layer, so within one layer's time) and lets what it
  // throws leave ditherLayers. A ditherer left that way must be reset() before it streams again.
  std::function<void()> checkInterrupt;
};

// The size of the bands a ditherer will be given, for memory estimates made before a slice starts
// (slicer::sliceMemoryBytes takes them from voxel::RasterEstimate).
struct DitherBand {
  double layerVoxels = 0.0;  // active voxels of the fullest layer
  double leaves = 0.0;       // leaves (8^3 voxels) of the fullest band's fraction grid, next layer included
  int layers = 0;            // layers per band
};

class Ditherer {
public:
  virtual ~Ditherer() = default;
  virtual std::string_view name() const = 0;

  // Whether ditherLayers reads layer k1 past the band as well (error diffusion: see ditherLayers), so a
  // caller that builds one fraction grid per band includes that layer. Pure, so that a ditherer wrapping
  // another (slicer::BarCountingDitherer) must pass it on.
  virtual bool readsNextLayer() const = 0;

  // Bytes the ditherer holds at most while it dithers bands of `band`'s size, called from a task arena
  // of `concurrency` threads (tbb::this_task_arena::max_concurrency() where ditherLayers will be
  // called), besides its input (the band's fraction grid) and its output (the material grid, its
  // leaves and nodes): its lists of the band's leaves, buffers per layer and per worker, and what it
  // keeps from band to band. An upper estimate (each implementation says what it counts and how it was
  // measured); 0 or more, no throw. Thread-safe: reads nothing that dithering changes.
  virtual double workingBytes(const DitherBand& band, int concurrency) const = 0;

  // Output (material) trees let go of that the ditherer keeps, to build later bands' trees from their
  // nodes (its voxel::TreeRecycler's keptTrees()): a memory estimate counts them at a band's material
  // tree each, besides workingBytes. No throw; thread-safe.
  virtual std::size_t keptTrees() const = 0;

  // Dithers the active voxels of layers [k0, k1) of `fraction`; the result holds exactly those voxels.
  // Throws std::invalid_argument for k0 > k1 or a fraction outside [0, 1] (naming the voxel).
  // "error-diffusion" carries error from one layer into the next, so for it:
  //   - bands must come in order, each starting where the previous ended (std::logic_error otherwise);
  //     the first band must start at or below the part's first layer;
  //   - layer k1 is read too (its active voxels only: they are where error can go), so a caller that
  //     builds one fraction grid per band includes one layer past the band, and the next band's grid
  //     must agree with it.
  // Active tiles in `fraction` are dithered voxel by voxel (on a voxelized copy: costs memory).
  openvdb::BoolGrid::Ptr ditherLayers(const openvdb::FloatGrid& fraction, int k0, int k1);

  // Maps layers [k0, k1) of a "modulus_mpa" grid (E in MPa, active voxels = the part) to Vero fractions
  // with `map` and dithers them: the same material grid as
  //   ditherLayers(*mapToFractions(modulus, map, k0, k1, stats), k0, k1)
  // bit for bit, and the same counts added to `stats` (left unchanged when something throws). The
  // pointwise ditherers (white, blue; mapsWhileDithering()) map each leaf into a buffer of 512 floats
  // and dither it at once, building no fraction grid; the others map the band into a fraction grid
  // first (error diffusion: layer k1 as well, not counted, since it reads that layer). Throws as
  // ditherLayers (std::invalid_argument for k0 > k1; no fraction check is needed, a FractionMap's
  // values lie in [0, 1]); interrupts as DitherOptions::checkInterrupt says. Active tiles in `modulus`
  // are mapped voxel by voxel (on a voxelized copy). Threads: runs in the caller's TBB arena; the
  // result and the counts do not depend on the thread count. Not for concurrent calls on one ditherer.
  openvdb::BoolGrid::Ptr mapAndDitherLayers(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                            MappingStats& stats);

  // Whether mapAndDitherLayers builds no fraction grid (white, blue), so a slicer can leave the
  // mapping to it and a memory estimate counts no fraction trees. False unless a ditherer overrides
  // mapAndDitherLeafVoxels to fuse: a wrapper that does not pass both on keeps the default pair, which
  // agree. No throw; thread-safe.
  virtual bool mapsWhileDithering() const { return false; }

  // Forgets streaming state, so the next band may start anywhere.
  virtual void reset() {}

  // The whole grid at once (resets first).
  openvdb::BoolGrid::Ptr dither(const openvdb::FloatGrid& fraction);

protected:
  // ditherLayers for a grid whose active voxels all sit in leaves, with k0 <= k1.
  virtual openvdb::BoolGrid::Ptr ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) = 0;
  // mapAndDitherLayers for a modulus grid whose active voxels all sit in leaves, with k0 <= k1. The
  // default maps the band (and layer k1 when readsNextLayer()) into a fraction grid and calls
  // ditherLeafVoxels; a ditherer that overrides it to fuse says so in mapsWhileDithering().
  virtual openvdb::BoolGrid::Ptr mapAndDitherLeafVoxels(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0,
                                                        int k1, MappingStats& stats);
};

// "white": Vero where a counter-based uniform number of (seed, i, j, k) is below the fraction (mezzotint).
// "blue": Vero where the fraction exceeds the tiled blue-noise mask's threshold; the seed shifts the tiling.
// "error-diffusion": 3D serpentine Floyd-Steinberg renormalized over the part, most error carried to the
//   voxel above; the seed jitters the threshold. A wavefront over the layers on up to 4 threads.
// Measured quality: materials/README.md and `rodfab dither-report`.
const std::vector<std::string>& ditherMethodNames();

// True when `name`, or the name canonicalDitherName gives it, is one of ditherMethodNames().
bool isDitherMethod(const std::string& name);
// "white, blue, error-diffusion": the names for a message saying what was expected.
std::string ditherMethodList();

// The ditherer's name as calibration data and job manifests record it: "random" (the published
// pipeline's word) and "white-noise" mean "white", "blue-noise" means "blue"; other names are
// returned unchanged (makeDitherer then judges them).
std::string canonicalDitherName(const std::string& name);

// Throws std::invalid_argument naming the valid names for an unknown `method`, and
// std::runtime_error when "blue" needs the bundled mask and it cannot be read.
std::unique_ptr<Ditherer> makeDitherer(std::string_view method, const DitherOptions& options = {});

}  // namespace rodfab::materials
