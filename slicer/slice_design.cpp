#include "slicer/slice_design.hpp"

#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "common/stopwatch.hpp"
#include "slicer/job_report.hpp"
#include "voxel/diagnostics.hpp"
#include "voxel/tree_assembly.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <thread>

namespace rodfab::slicer {

namespace {

using Clock = std::chrono::steady_clock;
using common::secondsSince;

// report.html (job_report.hpp), made when the writer finalizes the job: the bands are done by then.
printer_profiles::JobReportHook reportHook(const SliceReport& report, const calibration::Calibration& calibration,
                                           const ClampMap& clamps, bool verified) {
  return [&report, &calibration, &clamps, verified](const nlohmann::json& manifest, const auto& previews) {
    ReportInputs inputs;
    inputs.verified = verified;
    inputs.calibration = &calibration;
    inputs.clamps = &clamps;
    inputs.warnings = report.warnings;
    const auto empty = std::count(report.voxelsPerRod.begin(), report.voxelsPerRod.end(), std::uint64_t{0});
    if (empty > 0)
      inputs.warnings.push_back(std::to_string(empty) + " rod(s) hold no voxel centre (thinner than the voxel or hidden in "
                                "other rods): they are not printed; rodfab voxelize --json lists them");
    const std::string page = renderJobReport(manifest, previews, inputs);
    return printer_profiles::Bytes(page.begin(), page.end());
  };
}

// Refuses a slice whose estimate exceeds the memory budget, naming the design and what to change.
// Returns the estimate.
std::uint64_t requireSliceMemory(const geometry::RodStructure& design, const voxel::PrinterGrid& grid, int bandLayers,
                                 std::string_view ditherer, std::size_t pieces, const SliceSettings& settings) {
  const std::string name = settings.designFile.empty() ? "the design" : settings.designFile;
  const std::uint64_t bytes = sliceMemoryBytes(design, grid, bandLayers, ditherer, settings.threads, pieces);
  common::requireMemory(bytes,
                        "slicing " + name + " (" + std::to_string(design.rods.size()) + " rod(s)) in bands of " +
                            std::to_string(bandLayers) + " layers",
                        bandLayers > kLeafLayers ? "use fewer --band-layers (" + std::to_string(kLeafLayers) +
                                                       " at least), or raise --max-memory if the machine has more"
                                                 : "slice a smaller design, or raise --max-memory if the machine has more");
  return bytes;
}

// Error diffusion's buffers (materials/error_diffusion.cpp): a slot per layer in progress, min(threads, 4)
// + 3 of them but no more than the band's layers and the next, each ~36 bytes per active voxel of the
// layer (coordinates, fraction, threshold, links, neighbours, error) with vector growth's slack up to
// twice that. Measured: 360 bytes per voxel of a full 2000 x 1000 layer at 2 threads in 8-layer bands.
double errorDiffusionBytes(const voxel::RasterEstimate& raster, int bandLayers, int threads) {
  constexpr double kSlotBytesPerVoxel = 80.0;
  const int workers = std::clamp(threads > 0 ? threads : int(std::thread::hardware_concurrency()), 1, 4);
  const int slots = std::min(workers + 3, bandLayers + 1);
  return slots * kSlotBytesPerVoxel * raster.layerVoxels;
}

}  // namespace

std::uint64_t sliceMemoryBytes(const geometry::RodStructure& design, const voxel::PrinterGrid& grid, int bandLayers,
                               std::string_view ditherer, int threads, std::optional<std::size_t> pieces) {
  voxel::RasterEstimate raster = voxel::estimateRaster(design, grid, bandLayers);
  if (pieces) raster.pieceBytes = double(*pieces) * voxel::RasterEstimate::bytesPerPiece();
  // The dithered bands' material (bool) trees: the bands in flight and the ditherer's recycler's kept
  // ones, on the band's leaves (a bool leaf: two 64-byte masks and its origin, plus the allocator's header).
  constexpr double kMaterialTrees = kBandsInFlight + double(voxel::TreeRecycler<openvdb::BoolTree>::kKeptTrees);
  const double materialBytes = kMaterialTrees * raster.bandLeaves * (double(sizeof(openvdb::BoolTree::LeafNodeType)) + 16.0);
  // Explicit support's column tops: an int per column of the part.
  const openvdb::Coord part = designVoxelBounds(design, grid).dim();
  const double supportBytes = 4.0 * double(part.x()) * double(part.y());
  const double ditherBytes = ditherer == "error-diffusion" ? errorDiffusionBytes(raster, bandLayers, threads) : 0.0;
  const double bytes = raster.peakBytes(kBandsInFlight) + materialBytes + supportBytes + ditherBytes +
                       double(jobWriterBytes(designVoxelBounds(design, grid)));
  return common::saturatedBytes(bytes);
}

openvdb::CoordBBox designVoxelBounds(const geometry::RodStructure& design, const voxel::PrinterGrid& grid) {
  const geometry::Box3 box = design.bounds();
  return grid.voxelsWithin({box.min().x(), box.min().y(), box.min().z()}, {box.max().x(), box.max().y(), box.max().z()});
}

int automaticBandLayers(const openvdb::CoordBBox& partBounds) {
  // ~21 M voxels a band (32 M before the stages overlapped): with two bands in flight in streamJob,
  // the pipeline's buffers and the writer's staging come on top of the bands. Whole leaf slabs: a
  // band of fewer layers would hold a slab's leaves anyway (a 400 x 40 mm coupon plate at 1 layer a
  // band: 1.33 GB and 39 s for 50 layers; at 8: 1.28 GB and 18.7 s).
  constexpr double kBandVoxels = 21.0 * (1 << 20);
  const double layerVoxels = std::max(1.0, double(partBounds.dim().x()) * double(partBounds.dim().y()));
  const double slabs = std::clamp(std::floor(kBandVoxels / (kLeafLayers * layerVoxels)), 1.0, 8.0);
  return kLeafLayers * static_cast<int>(slabs);
}

SliceReport sliceDesign(const geometry::RodStructure& design, const printer_profiles::Profile& profile,
                        const calibration::Calibration& calibration, materials::Ditherer& ditherer,
                        const SliceSettings& settings) {
  SliceReport report;
  auto start = Clock::now();
  const voxel::PrinterGrid grid =
      voxel::makePrinterGrid(design, profile.voxelSize());
  const openvdb::CoordBBox partBounds = designVoxelBounds(design, grid);
  const int bandLayers = settings.bandLayers > 0 ? settings.bandLayers : automaticBandLayers(partBounds);
  for (const voxel::ThinRod& thin : voxel::findThinRods(design, grid)) report.warnings.push_back(thin.reason);
  // The pieces are bounded by the rods' budgets (rod_pieces.hpp); the bands are checked against the
  // budget with the pieces' real count, which is often a tenth of the budgets' bound.
  const voxel::Rasterizer rasterizer(design, grid, {settings.threads, common::interruptRequested});
  report.bandLayers = bandLayers;
  report.memoryEstimateBytes = requireSliceMemory(design, grid, bandLayers, ditherer.name(), rasterizer.pieceCount(), settings);
  const materials::FractionMap fractionMap(calibration);
  report.floorMpa = fractionMap.floorMpa();
  report.floorFraction = fractionMap.floorFraction();
  report.maxModulusMpa = fractionMap.maxModulusMpa();
  report.prepareSeconds = secondsSince(start);

  printer_profiles::JobSpec spec;
  spec.profile = profile;
  spec.partBounds = partBounds;
  spec.originMm = grid.origin;
  spec.metadata.design = settings.designFile;
  if (!settings.designSha256.empty()) spec.metadata.extra["design_sha256"] = settings.designSha256;
  spec.metadata.ditherer = std::string(ditherer.name());
  spec.metadata.seed = settings.seed;
  if (!settings.calibrationFile.empty())
    spec.metadata.calibration = printer_profiles::CalibrationRecord{settings.calibrationFile, settings.calibrationSha256,
                                                                    calibration.record().rigidMaterial,
                                                                    calibration.record().rubberyMaterial, settings.calibrationWarning};
  spec.options = settings.job;
  if (settings.job.support.value_or(profile.supportPolicy) == printer_profiles::SupportPolicy::Explicit) {
    // Support reaches down from every overhang, so the column tops of the whole part come first: a
    // topology-only pass over the bands (each band's grid is dropped as soon as it is counted).
    start = Clock::now();
    auto tops = std::make_shared<printer_profiles::ColumnTops>(printer_profiles::planJob(profile, spec.partBounds));
    for (int k0 = spec.partBounds.min().z(); k0 <= spec.partBounds.max().z(); k0 += bandLayers)
      tops->include(*rasterizer.rasterizeLayers(k0, std::min(spec.partBounds.max().z() + 1, k0 + bandLayers)).grid);
    spec.supportTops = tops;
    report.supportSeconds = secondsSince(start);
  }

  report.voxelsPerRod.assign(design.rods.size(), 0);
  ClampMap clampMap(spec.partBounds, profile.voxelSizeMm, fractionMap.floorMpa(), fractionMap.maxModulusMpa());
  spec.options.report = reportHook(report, calibration, clampMap, spec.options.verify);
  // The bands' fraction trees come back here once the pipeline is done with them, and later bands are
  // built from their nodes (the rasterizer recycles its own trees the same way).
  voxel::TreeRecycler<openvdb::FloatTree> fractionTrees(0.0f);
  const BandSource source = [&](int k0, int k1, bool withNextLayer) {
    const voxel::Rasterization ras = rasterizer.rasterizeLayers(k0, k1 + (withNextLayer ? 1 : 0));
    const std::uint64_t clampedBefore = report.mapping.clamps.total();
    for (std::size_t r = 0; r < report.voxelsPerRod.size(); ++r) report.voxelsPerRod[r] += ras.voxelsPerRod[r];
    BandGrids band{materials::mapToFractions(*ras.grid, fractionMap, k0, k1, report.mapping, fractionTrees, common::throwIfInterrupted),
                   ras.grid};
    if (withNextLayer) {
      // Error diffusion reads the next layer's voxels; they are counted with their own band.
      materials::MappingStats ignored;
      band.fraction->tree().merge(materials::mapToFractions(*ras.grid, fractionMap, k1, k1 + 1, ignored)->tree());
    }
    // Where the clamped voxels are, for the report's picture: voxel by voxel only in bands that have any.
    if (report.mapping.clamps.total() > clampedBefore) clampMap.add(*ras.grid, k0, k1);
    else clampMap.addOutline(*ras.grid, k0, k1);
    return band;
  };
  PipelineOptions pipeline;
  pipeline.bandLayers = bandLayers;
  pipeline.onBand = settings.onBand;
  pipeline.beforeFinalize = [&](printer_profiles::JobMetadata& metadata) {
    // Every band is written: the trees kept for reuse would only sit through the zip and its check.
    rasterizer.releaseSpareTrees();
    fractionTrees.releaseKept();
    metadata.clamping = printer_profiles::ModulusClamping{fractionMap.floorMpa(), fractionMap.maxModulusMpa(),
                                                          report.mapping.clamps.belowFloor, report.mapping.clamps.aboveMax};
  };
  report.job = streamJob(std::move(spec), source, ditherer, pipeline, report.seconds);
  return report;
}

}  // namespace rodfab::slicer
