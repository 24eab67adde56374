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
#include <cstdio>
#include <memory>
#include <vector>

namespace rodfab::slicer {

namespace {

using Clock = std::chrono::steady_clock;
using common::secondsSince;

// report.html (job_report.hpp), made when the writer finalizes the job: the bands are done by then.
printer_profiles::JobReportHook reportHook(const SliceReport& report, const calibration::Calibration& calibration,
                                           const ClampMap& clamps, const SliceSettings& settings, bool verified) {
  return [&report, &calibration, &clamps, &settings, verified](const nlohmann::json& manifest, const auto& previews) {
    ReportInputs inputs;
    inputs.verified = verified;
    inputs.calibration = &calibration;
    inputs.clamps = &clamps;
    if (!settings.calibrationWarning.empty()) inputs.warnings.push_back(settings.calibrationWarning);
    inputs.warnings.insert(inputs.warnings.end(), settings.inputWarnings.begin(), settings.inputWarnings.end());
    inputs.warnings.insert(inputs.warnings.end(), report.warnings.begin(), report.warnings.end());
    const auto empty = std::count(report.voxelsPerRod.begin(), report.voxelsPerRod.end(), std::uint64_t{0});
    if (empty > 0)
      inputs.warnings.push_back(std::to_string(empty) + " rod(s) hold no voxel centre (thinner than the voxel or hidden in "
                                "other rods): they are not printed; rodfab voxelize --json lists them");
    const std::string page = renderJobReport(manifest, previews, inputs);
    return printer_profiles::Bytes(page.begin(), page.end());
  };
}

// The band sizes an automatic choice of `automatic` layers falls back to when its estimate exceeds the
// budget, largest first: whole leaf slabs down to one (a band's grids hold whole slabs, so these shrink
// the bands' trees), then 4, 2 and 1 layers (as many slabs of leaves as a band of 8, but fewer of error
// diffusion's layer slots: on a full 2000 x 1000 layer, 2 slots instead of 5 are 490 MB less).
std::vector<int> smallerBands(int automatic) {
  std::vector<int> bands;
  for (int layers = (automatic - 1) / kLeafLayers * kLeafLayers; layers >= kLeafLayers; layers -= kLeafLayers) bands.push_back(layers);
  for (int layers : {4, 2, 1})
    if (layers < automatic) bands.push_back(layers);
  return bands;
}

// The job's geometry, what it was made from (recorded in its manifest) and the settings' job options.
printer_profiles::JobSpec jobSpec(const printer_profiles::Profile& profile, const openvdb::CoordBBox& partBounds,
                                  const voxel::PrinterGrid& grid, const calibration::Calibration& calibration,
                                  const materials::Ditherer& ditherer, const SliceSettings& settings) {
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
  return spec;
}

std::string smallerBandsNote(int bandLayers, int automatic) {
  return "sliced in bands of " + std::to_string(bandLayers) + " layer(s) instead of " + std::to_string(automatic) +
         " to stay within the memory budget of " + common::formatBytes(common::memoryBudget()) +
         ", which is slower: raise --max-memory if the machine has more";
}

// A --max-memory value at or above `bytes`: whole MiB below 1 GiB ("384M"), else tenths of a GiB ("1.8G"),
// rounded up (formatBytes rounds to nearest: "at least 1.7 GiB" for 1.74 GiB would not be enough).
std::string maxMemoryAtLeast(std::uint64_t bytes) {
  constexpr double kMiB = 1 << 20, kGiB = 1 << 30;
  char text[32];
  if (double(bytes) < kGiB) std::snprintf(text, sizeof text, "%.0fM", std::ceil(double(bytes) / kMiB));
  else std::snprintf(text, sizeof text, "%.1fG", std::ceil(double(bytes) / (0.1 * kGiB)) * 0.1);
  return text;
}

// Fraction trees sliceDesign's recycler keeps: those of the bands in flight, let go while the next are made.
constexpr std::size_t kFractionTreesKept = kBandsInFlight;

// sliceDesign's bands: rasterized by the source stage, their moduli mapped to fractions there (for a
// ditherer that reads fraction grids: error diffusion) or by the dither stage as it dithers (white and
// blue: Ditherer::mapAndDitherLayers, no fraction grid), with the mapping's counts, the voxels each rod
// won and the report's clamp picture added up band by band. make() is the pipeline's source,
// mapAndDither() its dither stage when mapsWhileDithering(); each is called one band at a time.
class SliceBands {
public:
  SliceBands(const voxel::Rasterizer& rasterizer, const materials::FractionMap& map, materials::Ditherer& ditherer,
             SliceReport& report, ClampMap& clamps)
      : rasterizer_(rasterizer), map_(map), ditherer_(ditherer), report_(report), clamps_(clamps),
        fused_(ditherer.mapsWhileDithering()) {}
  bool mapsWhileDithering() const { return fused_; }

  BandGrids make(int k0, int k1, bool withNextLayer) {
    const voxel::Rasterization ras = rasterizer_.rasterizeLayers(k0, k1 + (withNextLayer ? 1 : 0));
    for (std::size_t r = 0; r < report_.voxelsPerRod.size(); ++r) report_.voxelsPerRod[r] += ras.voxelsPerRod[r];
    if (fused_) return BandGrids{nullptr, ras.grid};  // mapped by mapAndDither
    materials::MappingStats counts;
    BandGrids band{materials::mapBandToFractions(*ras.grid, map_, k0, k1, withNextLayer, counts, fractionTrees_, common::throwIfInterrupted),
                   ras.grid};
    addMapped(counts, *ras.grid, k0, k1);
    return band;
  }

  openvdb::BoolGrid::Ptr mapAndDither(const BandGrids& band, int k0, int k1) {
    materials::MappingStats counts;
    openvdb::BoolGrid::Ptr material = ditherer_.mapAndDitherLayers(*band.modulus, map_, k0, k1, counts);
    addMapped(counts, *band.modulus, k0, k1);
    return material;
  }

  // Every band is written: the fraction trees kept for reuse would only sit through the zip and its check.
  void releaseKept() { fractionTrees_.releaseKept(); }

private:
  void addMapped(const materials::MappingStats& counts, const openvdb::FloatGrid& modulus, int k0, int k1) {
    report_.mapping.voxels += counts.voxels;
    report_.mapping.clamps += counts.clamps;
    // Where the clamped voxels are, for the report's picture: voxel by voxel only in bands that have any.
    if (counts.clamps.total() > 0) clamps_.add(modulus, k0, k1);
    else clamps_.addOutline(modulus);
  }

  const voxel::Rasterizer& rasterizer_;
  const materials::FractionMap& map_;
  materials::Ditherer& ditherer_;
  SliceReport& report_;
  ClampMap& clamps_;
  const bool fused_;
  // The bands' fraction trees come back here once the pipeline is done with them, and later bands are
  // built from their nodes (the rasterizer recycles its own trees the same way). Unused when fused_.
  voxel::TreeRecycler<openvdb::FloatTree> fractionTrees_{0.0f, kFractionTreesKept};
};

// What sliceMemoryBytes reads besides the design's raster profile and the band size.
struct SliceMemoryInputs {
  openvdb::Coord part;  // the part's voxels along x, y, z (designVoxelBounds)
  const materials::Ditherer& ditherer;  // its working memory and kept trees are counted; outlives the inputs
  int concurrency = 1;
  std::uint64_t writerBytes = 0;
  KeptBandTrees kept;
  std::optional<std::size_t> pieces;
};

// Band trees RasterEstimate::peakBytes counts for the fractions that sliceDesign never holds at once:
// - a ditherer that maps as it dithers (SliceBands: white, blue) makes no fraction grid, so none of the
//   kBandsInFlight bands' fraction trees exists (and it keeps none: slicingKeptTrees);
// - one that reads fraction grids (error diffusion) builds each band's fraction tree from the nodes of a
//   tree the fraction recycler kept (TreeRecycler::takeSpares: the spares not used are freed, new nodes
//   made only past them), so that kept tree and the one built from it are one tree's memory: at most
//   kBandsInFlight + kept - 1 fraction trees at once.
// (The rasterizer's recycler builds the moduli the same way; they stay counted in full, the slack white
// and blue's thinner margins were measured with.)
double fractionBandTreesNotHeld(const SliceMemoryInputs& in) {
  const bool noFractionGrids = in.ditherer.mapsWhileDithering();
  const bool keptTreeBuildsNextBands = in.kept.fractions > 0;
  if (noFractionGrids) return double(kBandsInFlight);
  if (keptTreeBuildsNextBands) return 1.0;
  return 0.0;
}

// sliceMemoryBytes from the design's layer profile, built once for every band size tried.
std::uint64_t sliceMemoryBytes(const voxel::RasterProfile& profile, int bandLayers, const SliceMemoryInputs& in) {
  // The moduli and fractions hold the layer past the band only when the ditherer reads it.
  voxel::RasterEstimate raster = profile.estimate(bandLayers, in.ditherer.readsNextLayer());
  if (in.pieces) raster.pieceBytes = double(*in.pieces) * voxel::RasterEstimate::bytesPerPiece();
  // The dithered bands' material (bool) trees, on the leaves of the band's own layers: the bands in flight
  // and the ditherer's recycler's kept ones (a bool leaf: two 64-byte masks and its origin, plus the
  // allocator's header).
  const double materialTrees = kBandsInFlight + double(in.kept.materials);
  const double materialBytes = materialTrees * profile.estimate(bandLayers, false).bandLeaves *
                               (double(sizeof(openvdb::BoolTree::LeafNodeType)) + 16.0);
  // Explicit support's column tops: an int per column of the part.
  const double supportBytes = 4.0 * double(in.part.x()) * double(in.part.y());
  const double ditherBytes = in.ditherer.workingBytes({raster.layerVoxels, raster.bandLeaves, bandLayers}, in.concurrency);
  // peakBytes counts two float grids a band in flight, its moduli and its fractions, and every kept tree;
  // less the fraction trees never held.
  const double fractionTreesNotHeld = fractionBandTreesNotHeld(in) * raster.bandBytes;
  return common::saturatedBytes(raster.peakBytes(kBandsInFlight, in.kept.moduli + in.kept.fractions) - fractionTreesNotHeld +
                                materialBytes + supportBytes + ditherBytes + double(in.writerBytes));
}

struct SliceMemoryPlan {
  int bandLayers = 0;
  std::uint64_t bytes = 0;
};

// The band size and its estimate (sliceMemoryBytes) for a slice within the memory budget: the
// caller's band size, or the automatic one, or with an automatic choice over the budget, the largest
// of smallerBands that fits. Refuses (common::OutOfMemory) with what to change: more memory when the
// writer's fixed share alone is over the budget, fewer --band-layers for a band size given, a smaller
// design when no band size fits.
SliceMemoryPlan planSliceMemory(const geometry::RodStructure& design, const printer_profiles::Profile& profile,
                                const voxel::PrinterGrid& grid, const materials::Ditherer& ditherer, std::size_t pieces,
                                const SliceSettings& settings) {
  const std::string name = settings.designFile.empty() ? "the design" : settings.designFile;
  const openvdb::CoordBBox part = designVoxelBounds(design, grid);
  const std::uint64_t writer = jobWriterBytes(profile, part, settings.job.contactSheetLayers);
  // The ditherer's arena's concurrency too; the layer profile once for every band size tried.
  const SliceMemoryInputs inputs{part.dim(), ditherer, stageConcurrency(), writer, slicingKeptTrees(ditherer), pieces};
  const voxel::RasterProfile layers(design, grid);
  const auto estimate = [&](int bandLayers) { return SliceMemoryPlan{bandLayers, sliceMemoryBytes(layers, bandLayers, inputs)}; };
  const printer_profiles::JobGeometry job = printer_profiles::planJob(profile, part);
  const std::string images = std::to_string(job.width) + " x " + std::to_string(job.height) + " pixels";
  if (writer > common::memoryBudget()) {
    const std::uint64_t least = estimate(1).bytes;  // what the smallest band would need in all
    common::requireMemory(writer, {.what = "writing the job of " + name + " for the " + profile.printer + " (its layer images of " +
                                               images + ", previews and the process itself)",
                                   .remedy = "no band size makes that smaller: raise --max-memory to at least " +
                                             maxMemoryAtLeast(std::max(least, writer))});
  }
  SliceMemoryPlan plan = estimate(settings.bandLayers > 0 ? settings.bandLayers : automaticBandLayers(part));
  const std::string what = "slicing " + name + " (" + std::to_string(design.rods.size()) + " rod(s), layer images of " + images + ")";
  if (settings.bandLayers > 0) {
    int fits = 0;  // the most layers a band of which fits, if any
    for (int n = plan.bandLayers - 1; n >= 1 && fits == 0 && plan.bytes > common::memoryBudget(); --n)
      if (estimate(n).bytes <= common::memoryBudget()) fits = n;
    // The estimate does not fall with every layer less (bands hold whole leaves of 8 layers): the size
    // found is named, not a range.
    const std::string remedy = fits > 0 ? "use --band-layers " + std::to_string(fits) +
                                              " (the largest that fits), or raise --max-memory if the machine has more"
                                        : "slice a smaller design, or raise --max-memory if the machine has more";
    common::requireMemory(plan.bytes, {.what = what + " in bands of " + std::to_string(plan.bandLayers) + " layers", .remedy = remedy});
    return plan;
  }
  const std::vector<int> fallbacks = smallerBands(plan.bandLayers);
  SliceMemoryPlan least = plan;
  for (std::size_t n = 0; plan.bytes > common::memoryBudget() && n < fallbacks.size(); ++n) {
    plan = estimate(fallbacks[n]);
    if (plan.bytes <= least.bytes) least = plan;  // on a tie the smaller band: the message names the smallest tried
  }
  if (plan.bytes <= common::memoryBudget()) return plan;
  const bool smallest = least.bandLayers == fallbacks.back();
  // Beyond what --max-memory accepts (parseByteSize: at most 1e18 bytes) no value is worth suggesting.
  const std::string remedy = double(least.bytes) > 1e18 ? "slice a smaller design (no --max-memory value is that large)"
                                                        : "slice a smaller design, or raise --max-memory to at least " +
                                                              maxMemoryAtLeast(least.bytes) + " if the machine has that much";
  common::requireMemory(least.bytes, {.what = what,
                                      .condition = "even in bands of " + std::to_string(least.bandLayers) +
                                                   (least.bandLayers == 1 ? " layer" : " layers") +
                                                   (smallest ? " (the smallest band size tried)" : " (the least of the band sizes tried)"),
                                      .remedy = remedy});
  return least;
}

}  // namespace

KeptBandTrees slicingKeptTrees(const materials::Ditherer& ditherer) {
  // A ditherer that maps as it dithers leaves sliceDesign's fraction recycler empty.
  return {voxel::TreeRecycler<openvdb::FloatTree>::kKeptTrees, ditherer.mapsWhileDithering() ? 0 : kFractionTreesKept,
          ditherer.keptTrees()};
}

std::uint64_t sliceMemoryBytes(const geometry::RodStructure& design, const voxel::PrinterGrid& grid, int bandLayers,
                               const materials::Ditherer& ditherer, int concurrency, std::uint64_t writerBytes,
                               std::optional<std::size_t> pieces) {
  const SliceMemoryInputs inputs{designVoxelBounds(design, grid).dim(), ditherer, concurrency, writerBytes, slicingKeptTrees(ditherer),
                                 pieces};
  return sliceMemoryBytes(voxel::RasterProfile(design, grid), bandLayers, inputs);
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
  for (const voxel::ThinRod& thin : voxel::findThinRods(design, grid)) report.warnings.push_back(thin.reason);
  // The pieces are bounded by the rods' budgets (rod_pieces.hpp); the bands are checked against the
  // budget with the pieces' real count, which is often a tenth of the budgets' bound.
  const voxel::Rasterizer rasterizer(design, grid, {settings.threads, common::interruptRequested});
  const SliceMemoryPlan memory = planSliceMemory(design, profile, grid, ditherer, rasterizer.pieceCount(), settings);
  const int bandLayers = memory.bandLayers;
  report.bandLayers = bandLayers;
  report.memoryEstimateBytes = memory.bytes;
  const materials::FractionMap fractionMap(calibration);
  report.floorMpa = fractionMap.floorMpa();
  report.floorFraction = fractionMap.floorFraction();
  report.maxModulusMpa = fractionMap.maxModulusMpa();
  report.prepareSeconds = secondsSince(start);

  printer_profiles::JobSpec spec = jobSpec(profile, partBounds, grid, calibration, ditherer, settings);
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
  spec.options.report = reportHook(report, calibration, clampMap, settings, spec.options.verify);
  SliceBands bands(rasterizer, fractionMap, ditherer, report, clampMap);
  const BandSource source = [&](int k0, int k1, bool withNextLayer) { return bands.make(k0, k1, withNextLayer); };
  PipelineOptions pipeline;
  pipeline.bandLayers = bandLayers;
  pipeline.onBand = settings.onBand;
  report.mappedWhileDithering = bands.mapsWhileDithering();
  if (bands.mapsWhileDithering())
    pipeline.ditherBand = [&](const BandGrids& grids, int k0, int k1) { return bands.mapAndDither(grids, k0, k1); };
  pipeline.beforeFinalize = [&](printer_profiles::JobMetadata& metadata) {
    // Every band is written: the trees kept for reuse would only sit through the zip and its check.
    rasterizer.releaseSpareTrees();
    bands.releaseKept();
    metadata.clamping = printer_profiles::ModulusClamping{fractionMap.floorMpa(), fractionMap.maxModulusMpa(),
                                                          report.mapping.clamps.belowFloor, report.mapping.clamps.aboveMax};
  };
  report.job = streamJob(std::move(spec), source, ditherer, pipeline, report.seconds);
  // For the technician on stderr, not in the job's report: the band size changes the time, not the job.
  if (settings.bandLayers <= 0 && bandLayers < automaticBandLayers(partBounds))
    report.warnings.push_back(smallerBandsNote(bandLayers, automaticBandLayers(partBounds)));
  return report;
}

}  // namespace rodfab::slicer
