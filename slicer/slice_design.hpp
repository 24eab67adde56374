// `rodfab slice` without the command line: a rod design through voxel/, materials/ and the job
// writer into a print job, band by band (see job_pipeline.hpp). Used by the command and the
// end-to-end benchmark.
#pragma once

#include "calibration/calibration.hpp"
#include "geometry/rod.hpp"
#include "materials/materials.hpp"
#include "printer_profiles/printer_profiles.hpp"
#include "slicer/job_pipeline.hpp"
#include "voxel/voxel.hpp"

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rodfab::slicer {

struct SliceSettings {
  // The design's file name and SHA-256, recorded in the manifest (a name, not a path: jobs travel).
  std::string designFile, designSha256;
  // The calibration's file name and its SHA-256, recorded in the manifest (empty: not recorded).
  std::string calibrationFile, calibrationSha256;
  // Why the calibration's materials are not the profile's, recorded in the manifest ("" when they are;
  // see checkCalibrationMaterials).
  std::string calibrationWarning;
  // Said of the inputs before slicing (the ditherer is not the calibration coupons'): the job's report
  // lists them, after calibrationWarning and before the slice's own (SliceReport::warnings).
  std::vector<std::string> inputWarnings;
  std::uint64_t seed = 0;  // the ditherer's, recorded in the manifest
  int threads = 0;         // rasterizer workers (0 = all); callers limit TBB as a whole with global_control
  int bandLayers = 0;       // layers per band; 0: automatic (automaticBandLayers, fewer to fit the budget)
  printer_profiles::JobOptions job;
  // After every band: (layers done, layers in the part). May throw to abort; nothing is left behind.
  std::function<void(int, int)> onBand;
};

struct SliceReport {
  printer_profiles::JobResult job;
  materials::MappingStats mapping;          // model voxels and clamped moduli
  std::vector<std::uint64_t> voxelsPerRod;  // voxels each rod won
  int bandLayers = 0;                       // layers per band, as chosen (fewer than asked for when the
                                            // automatic size did not fit the memory budget)
  std::uint64_t memoryEstimateBytes = 0;    // sliceMemoryBytes, checked against the memory budget
  double prepareSeconds = 0.0;              // printer grid, rod pieces, fraction table
  double supportSeconds = 0.0;              // the column-top pre-pass of explicit support
  StageSeconds seconds;                     // bands: source (voxelize, and map unless mappedWhileDithering),
                                            // dither (and map), emit
  bool mappedWhileDithering = false;        // the moduli were mapped to fractions in the dither stage
                                            // (Ditherer::mapsWhileDithering), not in the source's
  double floorMpa = 0.0, floorFraction = 0.0, maxModulusMpa = 0.0;
  std::vector<std::string> warnings;       // for the technician: rods thinner than the printer resolves
};

// Index box of the voxel centres inside the design's bounding box in `grid`: every voxel the
// rasterizer can activate, known before any band is rasterized (the images are planned from it).
openvdb::CoordBBox designVoxelBounds(const geometry::RodStructure& design, const voxel::PrinterGrid& grid);

// Layers per band when the caller does not choose: 64, fewer when the part's layer box is so large
// that 64 dense layers would not stay within ~21 million voxels (a solid block must stream too); always
// whole 8-layer leaf slabs (kLeafLayers), so at least 8.
int automaticBandLayers(const openvdb::CoordBBox& partBounds);

// Band trees let go of that the recyclers keep for the next bands while a slice streams (each
// voxel::TreeRecycler's keptTrees()); sliceMemoryBytes counts each at a band's tree.
struct KeptBandTrees {
  std::size_t moduli = 0;     // the rasterizer's (voxel::Rasterizer keeps TreeRecycler's default)
  std::size_t fractions = 0;  // sliceDesign's, for the mapped fractions (0 for a ditherer that maps as
                              // it dithers: Ditherer::mapsWhileDithering, white and blue)
  std::size_t materials = 0;  // the ditherer's output trees (materials::Ditherer::keptTrees)
};
// What sliceDesign's recyclers keep when it slices with `ditherer`. No throw.
KeptBandTrees slicingKeptTrees(const materials::Ditherer& ditherer);

// Resident bytes `sliceDesign` needs at most for `design` on `grid` in bands of `bandLayers` layers,
// from the design alone (no band allocated): the rasterizer's pieces (`pieces` of them once built; the
// rods' piece budgets before) and band trees with kBandsInFlight bands in flight
// (voxel::RasterEstimate::peakBytes: moduli and fractions; the moduli only for a ditherer that maps as
// it dithers, Ditherer::mapsWhileDithering), the dithered material trees of those bands, the trees sliceDesign's
// recyclers keep (each at a band's tree: slicingKeptTrees(ditherer)),
// `ditherer`'s own buffers (materials::Ditherer::workingBytes in an arena of `concurrency` threads:
// stageConcurrency(), which follows --threads: error diffusion's workers' buffers), explicit
// support's column tops and `writerBytes` (the job writer's share, jobWriterBytes). An upper estimate:
// resident peaks measured on the benchmark classes and the examples are 1.3 to 2.7 times below it
// (slicer/README.md). Saturates (common::saturatedBytes) rather than overflows; throws
// std::bad_alloc if its per-layer tables (two doubles a layer of the grid) cannot be allocated.
// Thread-safe (reads its arguments only; `ditherer` through its const workingBytes and mapsWhileDithering).
std::uint64_t sliceMemoryBytes(const geometry::RodStructure& design, const voxel::PrinterGrid& grid, int bandLayers,
                               const materials::Ditherer& ditherer, int concurrency, std::uint64_t writerBytes,
                               std::optional<std::size_t> pieces = std::nullopt);

// Throws common::OutOfMemory, once the rods' pieces are built and before any band is, when the slice
// does not fit the memory budget (common/memory_budget.hpp): when the job writer's fixed share
// (jobWriterBytes) alone exceeds it (the message asks for more memory, as no band size helps), or when
// sliceMemoryBytes does for the band size given (settings.bandLayers), or, with an automatic band size,
// for every band size tried: the automatic one, then fewer whole 8-layer slabs, then 4, 2 and 1 layers;
// the first that fits is used (SliceReport::bandLayers). TrayFitError for a design the tray cannot
// hold, std::runtime_error for an output that exists (without force) or cannot be written; whatever
// `onBand` throws passes through.
SliceReport sliceDesign(const geometry::RodStructure& design, const printer_profiles::Profile& profile,
                        const calibration::Calibration& calibration, materials::Ditherer& ditherer,
                        const SliceSettings& settings);

}  // namespace rodfab::slicer
