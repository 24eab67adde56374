// The slicer's memory checks: couponJobBytes, sliceDesign's refusals and smaller bands under a budget,
// and the raster estimate of single rods against the grids the rasterizer builds.

#include "slicer_test_support.hpp"

using namespace rodfab;
using namespace slicer_test;

TEST_CASE("couponJobBytes counts error diffusion's layer slots over the bars' real footprints", "[memory]") {
  openvdb::initialize();
  const printer_profiles::Profile& p = connex3();
  const slicer::CouponLayout layout = slicer::planCouponLayout(p, 11, slicer::couponVoxels(p, {20, 4, 0.6}, 3));
  const std::vector<double> fractions(layout.bars.size(), 0.5);
  // Independent truth: the active voxels of a layer of the fraction band the coupons job dithers.
  const slicer::BandSource bands = slicer::couponBands(layout, fractions, p, openvdb::Vec3d(0.02, 0.04, 0.015));
  const openvdb::FloatGrid::Ptr band = bands(0, 8, false).fraction;
  double layerVoxels = 0.0;
  for (auto v = band->cbeginValueOn(); v; ++v) layerVoxels += v.getCoord().z() == 3 ? 1.0 : 0.0;
  REQUIRE(layerVoxels > 100'000);
  const auto ed = materials::makeDitherer("error-diffusion", {});
  const auto white = materials::makeDitherer("white", {});
  const double slots = double(slicer::couponJobBytes(layout, p, 16, 8, *ed)) - double(slicer::couponJobBytes(layout, p, 16, 8, *white));
  CAPTURE(layerVoxels, slots);
  CHECK(slots >= 2 * 34.0 * layerVoxels);   // at least two slots of ~34 bytes a voxel and more (materials/README.md)
  CHECK(slots <= 8 * 100.0 * layerVoxels);  // and not the whole tray's layer: at most 4 workers + 3 slots
}

TEST_CASE("sliceDesign refuses a slice over the memory budget before any band, writing nothing, the message says what to change") {
  openvdb::initialize();
  TempDir tmp;
  // A 200 x 200 x 3 mm plate: 11 M voxels a layer, 100 layers, several GB in bands of 64 layers.
  const geometry::NurbsCurve axis(1, {0, 0, 1, 1}, {{0, 100, 1.5}, {200, 100, 1.5}});
  const geometry::RodStructure design{"plate", {geometry::Rod("plate", axis, geometry::Section::rectangle(200.0, 3.0), geometry::Vec3(0, 1, 0),
                                                              std::nullopt, geometry::CapStyle::Flat, geometry::BSplineField::constant(20, 0, 1))}};
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, connex3().voxelSize());
  const SoftDataLimit limit(std::uint64_t{2} << 30);  // the torture suite's address-space cap
  REQUIRE(common::memoryBudget() <= (std::uint64_t{2} << 30));
  const auto ditherer = materials::makeDitherer("white", {});
  const std::uint64_t writer = slicer::jobWriterBytes(connex3(), slicer::designVoxelBounds(design, grid), 16);
  REQUIRE(slicer::sliceMemoryBytes(design, grid, 64, *ditherer, 1, writer) > common::memoryBudget());
  const calibration::Calibration cal = calibration::loadDefaultCalibration();
  slicer::SliceSettings settings;
  settings.designFile = "plate.json";
  settings.bandLayers = 64;
  settings.job.output = tmp.path / "plate.zip";
  // Not even a band of one layer fits: fewer --band-layers would not help, and the message does not say so.
  REQUIRE(slicer::sliceMemoryBytes(design, grid, 1, *ditherer, 1, writer) > common::memoryBudget());
  CHECK_THAT(memoryRefusal(design, cal, *ditherer, settings), Catch::Contains("plate.json") && Catch::Contains("bands of 64 layers") &&
                                                                 Catch::Contains("slice a smaller design") && Catch::Contains("--max-memory") &&
                                                                 !Catch::Contains("--band-layers"));
  CHECK(fs::is_empty(tmp.path));  // no job, nothing staged
}

TEST_CASE("the memory check passes the bundled examples under a 2 GiB cap, with the estimate above their real needs") {
  // Resident peaks (MB of 10^6 bytes) of `rodfab slice EXAMPLE --dither D --threads 2 --seed 7`, automatic
  // bands, the largest of three runs (/usr/bin/time's maximum resident set, KiB; 2026-12-03, tidy10: white
  // and blue map as they dither since pipe9, error diffusion's estimate tightened by tidy10). Each ditherer's
  // estimate must stay above its own peak (they were 259, 260 and 428 MB for arm-cast, 196, 197 and 269 for
  // buckling-spring, 245, 246 and 461 for unfolding-box). The figures before (arm-cast 197.5, buckling-spring
  // 156.2, unfolding-box 223.7: the larger of white and error diffusion) predated the fused map-and-dither.
  struct MeasuredPeaks {
    const char* design;
    double white, blue, errorDiffusion;
  };
  const std::vector<MeasuredPeaks> measured{{"arm-cast", 129.7, 128.3, 185.6},
                                            {"buckling-spring", 108.8, 119.4, 138.7},
                                            {"unfolding-box", 110.6, 103.0, 208.5}};
  openvdb::initialize();
  const SoftDataLimit limit(std::uint64_t{2} << 30);
  for (const MeasuredPeaks& peaks : measured) {
    INFO(peaks.design);
    const geometry::RodStructure design = geometry::readDesign(fs::path("examples") / (std::string(peaks.design) + ".json"));
    const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, connex3().voxelSize());
    const voxel::Rasterizer rasterizer(design, grid);
    const int automatic = slicer::automaticBandLayers(slicer::designVoxelBounds(design, grid));
    const std::uint64_t writer = slicer::jobWriterBytes(connex3(), slicer::designVoxelBounds(design, grid), 16);
    for (const auto& [name, peakMb] : {std::pair{"white", peaks.white}, std::pair{"blue", peaks.blue},
                                       std::pair{"error-diffusion", peaks.errorDiffusion}}) {
      INFO(name);
      const auto ditherer = materials::makeDitherer(name, {});
      for (int bandLayers : {1, 8, 64})
        CHECK(slicer::sliceMemoryBytes(design, grid, bandLayers, *ditherer, 2, writer, rasterizer.pieceCount()) <= common::memoryBudget());
      CHECK(double(slicer::sliceMemoryBytes(design, grid, automatic, *ditherer, 2, writer, rasterizer.pieceCount())) >= peakMb * 1e6);
    }
  }
}

namespace {

// A box of `sizeMm` (x, y, z) from the origin, as one straight rod of rectangular section along x.
geometry::RodStructure blockDesign(const std::string& name, double x, double y, double z) {
  const geometry::NurbsCurve axis(1, {0, 0, 1, 1}, {{0, y / 2, z / 2}, {x, y / 2, z / 2}});
  return {name, {geometry::Rod(name, axis, geometry::Section::rectangle(y, z), geometry::Vec3(0, 1, 0), std::nullopt,
                               geometry::CapStyle::Flat, geometry::BSplineField::constant(20, 0, 1))}};
}

}  // namespace

TEST_CASE("sliceDesign with an automatic band size over the memory budget slices in the largest smaller band that fits, the same bytes",
          "[memory]") {
  if (ranInFreshProcess("sliceDesign with an automatic band size over the memory budget slices in the largest smaller band that fits*"))
    return;
  openvdb::initialize();
  TempDir tmp;
  // A 10 x 10 x 10 mm block: 28 k voxels a layer, so 64 layers a band automatically.
  const geometry::RodStructure design = blockDesign("block", 10.0, 10.0, 10.0);
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, connex3().voxelSize());
  const openvdb::CoordBBox part = slicer::designVoxelBounds(design, grid);
  const int automatic = slicer::automaticBandLayers(part);
  REQUIRE(automatic == 64);
  const auto ditherer = materials::makeDitherer("error-diffusion", {});
  const calibration::Calibration cal = calibration::loadDefaultCalibration();
  const voxel::Rasterizer rasterizer(design, grid);
  const int concurrency = tbb::this_task_arena::max_concurrency();
  const std::uint64_t writer = slicer::jobWriterBytes(connex3(), part, 16);
  const auto estimate = [&](int bandLayers) {
    return slicer::sliceMemoryBytes(design, grid, bandLayers, *ditherer, concurrency, writer,
                                    rasterizer.pieceCount());
  };
  REQUIRE(estimate(64) > estimate(32));
  REQUIRE(estimate(32) > estimate(8));
  // A budget between bands of 32 and of 40 layers: 40 and above are refused, 32 is the largest that fits.
  const std::uint64_t budget = (estimate(32) + estimate(40)) / 2;
  REQUIRE(estimate(40) > budget);
  slicer::SliceSettings settings;
  settings.designFile = "block.json";
  fs::create_directories(tmp.path / "small");
  fs::create_directories(tmp.path / "large");
  settings.job.output = tmp.path / "small" / "block.zip";  // the same name: the manifest records it
  slicer::SliceReport small;
  {
    const SoftDataLimit limit(budget / 4 * 5);  // the default budget is 80 % of it
    REQUIRE(common::memoryBudget() < estimate(40));
    REQUIRE(common::memoryBudget() >= estimate(32));
    small = slicer::sliceDesign(design, connex3(), cal, *ditherer, settings);
  }
  CHECK(small.bandLayers == 32);
  CHECK(small.memoryEstimateBytes == estimate(32));
  REQUIRE(printer_profiles::inspectJob(small.job.path).ok());
  // Without the limit: bands of 64, the same job.
  settings.job.output = tmp.path / "large" / "block.zip";
  const slicer::SliceReport large = slicer::sliceDesign(design, connex3(), cal, *ditherer, settings);
  CHECK(large.bandLayers == 64);
  CHECK_FALSE(large.mappedWhileDithering);  // error diffusion reads fractions: mapped by the source
  CHECK(fileBytes(small.job.path) == fileBytes(large.job.path));
  // The technician is told why it took longer; the job (its report included) does not change.
  const auto told = [](const slicer::SliceReport& report) {
    return std::count_if(report.warnings.begin(), report.warnings.end(),
                         [](const std::string& w) { return w.find("sliced in bands of 32 layer(s) instead of 64") != std::string::npos; });
  };
  CHECK(told(small) == 1);
  CHECK(told(large) == 0);
}

TEST_CASE("sliceDesign refuses when no band size fits the memory budget, naming the least estimate tried and not --band-layers", "[memory]") {
  openvdb::initialize();
  TempDir tmp;
  // A 200 x 200 x 3 mm plate: 11 M voxels a layer; even a band of 1 layer holds a slab of its leaves.
  const geometry::RodStructure design = blockDesign("plate", 200.0, 200.0, 3.0);
  const SoftDataLimit limit(std::uint64_t{2} << 30);
  const calibration::Calibration cal = calibration::loadDefaultCalibration();
  slicer::SliceSettings settings;
  settings.designFile = "plate.json";
  settings.job.output = tmp.path / "plate.zip";
  const auto ditherer = materials::makeDitherer("error-diffusion", {});
  const std::string message = memoryRefusal(design, cal, *ditherer, settings);
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, connex3().voxelSize());
  const openvdb::CoordBBox part = slicer::designVoxelBounds(design, grid);
  const printer_profiles::JobGeometry job = printer_profiles::planJob(connex3(), part);  // the images, margins included
  const std::string images = std::to_string(job.width) + " x " + std::to_string(job.height) + " pixels";
  CHECK_THAT(message, Catch::Contains("slicing plate.json (1 rod(s), layer images of " + images + ") needs about ") &&
                          Catch::Contains(" even in bands of 1 layer (the smallest band size tried), more than the memory budget") &&
                          Catch::Contains("raise --max-memory to at least ") && !Catch::Contains("--band-layers"));
  // The value it suggests is an option value that covers the estimate of the smallest band.
  const std::size_t at = message.find("at least ");
  REQUIRE(at != std::string::npos);
  const std::string suggested = message.substr(at + 9, message.find(' ', at + 9) - (at + 9));
  const std::optional<std::uint64_t> suggestedBytes = common::parseByteSize(suggested);
  REQUIRE(suggestedBytes);
  const voxel::Rasterizer rasterizer(design, grid);
  const std::uint64_t least = slicer::sliceMemoryBytes(design, grid, 1, *ditherer, slicer::stageConcurrency(), slicer::jobWriterBytes(connex3(), part, 16), rasterizer.pieceCount());
  CAPTURE(message, suggested, least);
  CHECK(*suggestedBytes >= least);
  CHECK(*suggestedBytes < least + (std::uint64_t{1} << 30) / 10 + 1);
  CHECK(fs::is_empty(tmp.path));  // no job, nothing staged
}

TEST_CASE("sliceDesign refuses a memory budget below the job writer's fixed share, saying so, whatever the band size", "[memory]") {
  openvdb::initialize();
  TempDir tmp;
  const geometry::RodStructure design = blockDesign("cube", 1.0, 1.0, 1.0);  // about 8,000 voxels
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, connex3().voxelSize());
  const std::uint64_t writer = slicer::jobWriterBytes(connex3(), slicer::designVoxelBounds(design, grid), 16);
  CHECK(writer > std::uint64_t{96} << 20);  // the process, the previews, however small the part
  CHECK(writer < std::uint64_t{120} << 20);
  const calibration::Calibration cal = calibration::loadDefaultCalibration();
  const auto ditherer = materials::makeDitherer("white", {});
  for (const int bandLayers : {0, 1}) {
    INFO("band layers " << bandLayers);
    slicer::SliceSettings settings;
    settings.designFile = "cube.json";
    settings.bandLayers = bandLayers;
    settings.job.output = tmp.path / "cube.zip";
    const SoftDataLimit limit(writer / 10 * 9 / 4 * 5);  // a budget of 90 % of the writer's share
    REQUIRE(common::memoryBudget() < writer);
    CHECK_THAT(memoryRefusal(design, cal, *ditherer, settings),
               Catch::Contains("writing the job of cube.json") && Catch::Contains("no band size makes that smaller") &&
                   Catch::Contains("raise --max-memory to at least") && !Catch::Contains("--band-layers"));
    CHECK(fs::is_empty(tmp.path));
  }
}

TEST_CASE("single rods' memory estimate: layer voxels and band leaves at or above the grid's, within 3 and 2 times",
          "[voxel][estimate][memory]") {
  openvdb::initialize();
  // Independent truth: the grids the rasterizer builds, counted. Bands of 8 layers as streamJob cuts
  // them (slab-aligned, one layer past the band for error diffusion).
  const auto oneRod = [](const char* name, geometry::NurbsCurve axis, geometry::Section section, geometry::CapStyle caps) {
    return geometry::RodStructure{name, {geometry::Rod(name, std::move(axis), section, geometry::Vec3(0, 1, 0), std::nullopt, caps,
                                                       geometry::BSplineField::constant(20, 0, 1))}};
  };
  const geometry::NurbsCurve level(1, {0, 0, 1, 1}, {{0, 2, 1}, {10, 2, 1}});
  const geometry::NurbsCurve tilted(1, {0, 0, 1, 1}, {{0, 2, 1}, {10, 2, 11}});
  // Level, then straight up at a corner: the corner's frame is the upright part's.
  const geometry::NurbsCurve corner(1, {0, 0, 0.5, 1, 1}, {{0, 2, 1}, {20, 2, 1}, {20, 2, 20}});
  const geometry::NurbsCurve stub(1, {0, 0, 1, 1}, {{0, 2, 2}, {6, 2, 2}});
  // A thin upright post 40 mm away, so that a layer of the envelope holds far more than the rods: an
  // estimate stuck at the envelope's layer would be seen.
  const auto withPost = [](geometry::RodStructure design) {
    const geometry::NurbsCurve post(1, {0, 0, 1, 1}, {{0, 40, 1}, {0, 40, 20}});
    design.rods.emplace_back("post", post, geometry::Section::circle(0.5), geometry::Vec3(1, 0, 0), std::nullopt,
                             geometry::CapStyle::Flat, geometry::BSplineField::constant(20, 0, 1));
    return design;
  };
  constexpr int kBandLayers = 8;
  // The flat one 4 mm wide, 5 layers tall (its bounding radius would spread it over 130 layers), at the
  // envelope's bottom; the round one 10 layers; the stub's round caps hold a fifth of its middle layer.
  const geometry::CapStyle flat = geometry::CapStyle::Flat, round = geometry::CapStyle::Round;
  for (const geometry::RodStructure& design :
       {oneRod("flat", level, geometry::Section::rectangle(4.0, 0.15), flat), oneRod("round", level, geometry::Section::circle(0.3), flat),
        oneRod("tilted", tilted, geometry::Section::rectangle(3.0, 0.5), flat), withPost(oneRod("corner", corner, geometry::Section::circle(1.0), flat)),
        oneRod("capped stub", stub, geometry::Section::circle(2.0), round)}) {
    INFO(design.source);
    const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, connex3().voxelSize());
    const voxel::Rasterizer rasterizer(design, grid);
    const openvdb::FloatGrid::Ptr whole = rasterizer.rasterize().grid;
    std::vector<double> perLayer(std::size_t(grid.dims.z()), 0.0);
    for (auto v = whole->cbeginValueOn(); v; ++v) perLayer[std::size_t(v.getCoord().z())] += 1.0;
    const double layerVoxels = *std::max_element(perLayer.begin(), perLayer.end());
    double bandLeaves = 0.0, ownLeaves = 0.0;  // the fullest band's, with the next layer and without it
    for (int k0 = 0; k0 < grid.dims.z(); k0 += kBandLayers) {
      bandLeaves = std::max(bandLeaves, double(rasterizer.rasterizeLayers(k0, std::min(grid.dims.z(), k0 + kBandLayers + 1)).grid->tree().leafCount()));
      ownLeaves = std::max(ownLeaves, double(rasterizer.rasterizeLayers(k0, std::min(grid.dims.z(), k0 + kBandLayers)).grid->tree().leafCount()));
    }
    const voxel::RasterEstimate e = voxel::estimateRaster(design, grid, kBandLayers);
    const voxel::RasterEstimate own = voxel::RasterProfile(design, grid).estimate(kBandLayers, false);
    CAPTURE(layerVoxels, e.layerVoxels, bandLeaves, e.bandLeaves, ownLeaves, own.bandLeaves);
    REQUIRE(layerVoxels > 500);
    CHECK(e.layerVoxels >= layerVoxels);
    CHECK(e.layerVoxels <= 3.0 * layerVoxels);
    CHECK(e.bandLeaves >= bandLeaves);
    CHECK(e.bandLeaves <= 2.0 * bandLeaves);
    // Without the next layer (white and blue noise), a band of whole slabs holds half the slabs.
    CHECK(own.bandLeaves >= ownLeaves);
    CHECK(own.bandLeaves <= 2.0 * ownLeaves);
    CHECK(own.bandLeaves <= e.bandLeaves);
  }
}

namespace {

// Passes bands to another ditherer, recording the concurrency of the task arena it was called from.
class ArenaRecordingDitherer final : public materials::Ditherer {
public:
  explicit ArenaRecordingDitherer(materials::Ditherer& inner) : inner_(inner) {}
  std::string_view name() const override { return inner_.name(); }
  bool readsNextLayer() const override { return inner_.readsNextLayer(); }
  double workingBytes(const materials::DitherBand& band, int concurrency) const override { return inner_.workingBytes(band, concurrency); }
  std::size_t keptTrees() const override { return inner_.keptTrees(); }
  void reset() override { inner_.reset(); }
  std::vector<int> arenas;

protected:
  openvdb::BoolGrid::Ptr ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) override {
    arenas.push_back(tbb::this_task_arena::max_concurrency());
    return inner_.ditherLayers(fraction, k0, k1);
  }

private:
  materials::Ditherer& inner_;
};

}  // namespace

TEST_CASE("sliceDesign maps white and blue noise's moduli as it dithers - the job, counts and report of mapping in the source, less memory") {
  openvdb::initialize();
  TempDir tmp;
  const calibration::Calibration cal = calibration::loadDefaultCalibration();
  // E from below the floor to above the stiffest mix along each rod: clamps of both kinds, in some bands.
  const geometry::NurbsCurve along(1, {0, 0, 1, 1}, {{0, 1, 1}, {4, 1, 1}});
  const geometry::NurbsCurve up(1, {0, 0, 1, 1}, {{2, 1, 0.5}, {2.5, 1.5, 3.5}});
  const geometry::RodStructure design{
      "clamped", {geometry::Rod("along", along, geometry::Section::circle(1.2), std::nullopt, std::nullopt, geometry::CapStyle::Flat,
                                geometry::BSplineField(1, {0, 0, 1, 1}, {0.5 * cal.floorMpa(), 1.5 * cal.maxModulusMpa()})),
                  geometry::Rod("up", up, geometry::Section::circle(0.8), std::nullopt, std::nullopt, geometry::CapStyle::Round,
                                geometry::BSplineField(1, {0, 0, 1, 1}, {1.2 * cal.maxModulusMpa(), 2 * cal.floorMpa()}))}};
  for (const char* method : {"white", "blue"})
    for (const int threads : {1, 2}) {
      INFO(method << ", " << threads << " thread(s)");
      const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
      const auto slice = [&](materials::Ditherer& ditherer, const char* folder) {
        fs::create_directories(tmp.path / folder);
        slicer::SliceSettings settings;
        settings.designFile = "clamped.json";
        settings.seed = 3;
        settings.bandLayers = 8;
        settings.job.output = tmp.path / folder / "clamped.zip";  // the same name: the previews' titles show it
        settings.job.force = true;
        return slicer::sliceDesign(design, connex3(), cal, ditherer, settings);
      };
      const auto fused = materials::makeDitherer(method, {3});
      const auto inner = materials::makeDitherer(method, {3});
      // Forwards ditherLeafVoxels only: the base class's map-then-dither, and mapsWhileDithering() false,
      // so sliceDesign maps in its source stage, as before the two were fused.
      ArenaRecordingDitherer fractionGrids(*inner);
      REQUIRE(fused->mapsWhileDithering());
      REQUIRE_FALSE(fractionGrids.mapsWhileDithering());
      const slicer::SliceReport mapped = slice(*fused, "fused");
      const slicer::SliceReport source = slice(fractionGrids, "source");
      CHECK(mapped.mapping.voxels == source.mapping.voxels);
      CHECK(mapped.mapping.clamps.belowFloor == source.mapping.clamps.belowFloor);
      CHECK(mapped.mapping.clamps.aboveMax == source.mapping.clamps.aboveMax);
      CHECK(mapped.mapping.clamps.belowFloor > 0);
      CHECK(mapped.mapping.clamps.aboveMax > 0);
      CHECK(mapped.voxelsPerRod == source.voxelsPerRod);
      REQUIRE(printer_profiles::inspectJob(mapped.job.path).ok());
      CHECK(fileBytes(mapped.job.path) == fileBytes(source.job.path));  // layers, previews, the report's clamp picture
      CHECK(mapped.memoryEstimateBytes < source.memoryEstimateBytes);  // no fraction grids
    }
}

TEST_CASE("a thread limit of 1 (--threads 1) sizes the stage arenas and the estimate - error diffusion plans and runs one worker, the same job",
          "[memory]") {
  openvdb::initialize();
  TempDir tmp;
  const geometry::RodStructure design = blockDesign("block", 6.0, 6.0, 2.0);
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, connex3().voxelSize());
  const openvdb::CoordBBox part = slicer::designVoxelBounds(design, grid);
  const voxel::Rasterizer rasterizer(design, grid);
  const std::uint64_t writer = slicer::jobWriterBytes(connex3(), part, 16);
  const calibration::Calibration cal = calibration::loadDefaultCalibration();
  const auto errorDiffusion = materials::makeDitherer("error-diffusion", {});
  const auto estimate = [&](int concurrency) {
    return slicer::sliceMemoryBytes(design, grid, slicer::automaticBandLayers(part), *errorDiffusion, concurrency, writer, rasterizer.pieceCount());
  };
  const auto slice = [&](const char* folder, std::vector<int>& arenas) {
    fs::create_directories(tmp.path / folder);
    slicer::SliceSettings settings;
    settings.designFile = "block.json";
    settings.job.output = tmp.path / folder / "block.zip";
    ArenaRecordingDitherer recording(*errorDiffusion);
    const slicer::SliceReport report = slicer::sliceDesign(design, connex3(), cal, recording, settings);
    arenas = recording.arenas;
    return report;
  };
  const int machine = tbb::this_task_arena::max_concurrency();
  std::vector<int> limitedArenas, freeArenas;
  slicer::SliceReport limited;
  {
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    CHECK(slicer::stageConcurrency() == 1);
    limited = slice("limited", limitedArenas);
  }
  CHECK(slicer::stageConcurrency() == machine);
  const slicer::SliceReport free = slice("free", freeArenas);
  REQUIRE_FALSE(limitedArenas.empty());
  CHECK(std::all_of(limitedArenas.begin(), limitedArenas.end(), [](int n) { return n == 1; }));
  CHECK(std::all_of(freeArenas.begin(), freeArenas.end(), [&](int n) { return n == machine; }));
  CHECK(limited.memoryEstimateBytes == estimate(1));
  CHECK(free.memoryEstimateBytes == estimate(machine));
  if (machine > 1) CHECK(limited.memoryEstimateBytes < free.memoryEstimateBytes);  // one worker's masks and slots fewer
  CHECK(fileBytes(limited.job.path) == fileBytes(free.job.path));
}
