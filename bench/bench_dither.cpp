// materials/: dithering throughput per ditherer (items = voxels, on all cores TBB gives), the
// modulus-to-fraction mapping and blue-noise mask generation. Peak resident memory as a counter.
#include "bench/bench_profile.hpp"
#include "common/stopwatch.hpp"
#include "calibration/calibration.hpp"
#include "examples/example_designs.hpp"
#include "materials/materials.hpp"
#include "voxel/voxel.hpp"

#include <benchmark/benchmark.h>

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

using namespace rodfab::materials;

namespace {

using rodfab::common::processCpuSeconds;

// The voxel of the benchmark's printer profile (bench/bench_profile.hpp).
const openvdb::Vec3d& benchVoxel() {
  static const openvdb::Vec3d voxel = rodfab::bench::benchVoxelMm();
  return voxel;
}

double peakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux reports KiB
}

// Dense workload: 256 x 128 x 192 voxels (10.8 x 10.8 x 5.8 mm), fractions varying smoothly 0.3 .. 0.9.
const openvdb::FloatGrid& denseBlock() {
  static const openvdb::FloatGrid::Ptr grid = [] {
    openvdb::initialize();
    auto g = makeUniformBlock(openvdb::Coord(256, 128, 192), 0.5f, benchVoxel());
    for (auto it = g->beginValueOn(); it; ++it) {
      const openvdb::Coord c = it.getCoord();
      it.setValue(0.6f + 0.3f * std::sin(0.02f * c.x()) * std::cos(0.03f * c.y() + 0.01f * c.z()));
    }
    return g;
  }();
  return *grid;
}

// Thin workload: 16 parallel rods of 1 mm diameter and 20 mm length along x, 2 mm apart, at 0.3.
const openvdb::FloatGrid& rodBundle() {
  static const openvdb::FloatGrid::Ptr grid = [] {
    openvdb::initialize();
    auto g = makeRod(1.0, 20.0, 0, 0.3f, benchVoxel());
    const auto one = g->deepCopy();
    for (int r = 1; r < 16; ++r) {
      const openvdb::Coord shift(0, static_cast<int>((r % 4) * 2.0 / benchVoxel()[1]),
                                 static_cast<int>((r / 4) * 2.0 / benchVoxel()[2]));
      auto acc = g->getAccessor();
      for (auto it = one->cbeginValueOn(); it; ++it) acc.setValueOn(it.getCoord() + shift, *it);
    }
    return g;
  }();
  return *grid;
}

// The bundled calibration's table, as `rodfab slice` maps with it.
const FractionMap& bundledMap() {
  static const FractionMap map(rodfab::calibration::loadDefaultCalibration());
  return map;
}

// Lattice workload: 400 layers (a 12 mm slab) from the middle of the `lattice` benchmark class
// (examples::benchmarkDesign), rasterized as `rodfab slice` does: its moduli, and (latticeSlab) its
// fractions through the bundled calibration: rods a few leaves across, most leaves partly filled.
const openvdb::FloatGrid& latticeModulusSlab() {
  static const openvdb::FloatGrid::Ptr grid = [] {
    openvdb::initialize();
    const rodfab::geometry::RodStructure design = rodfab::examples::benchmarkDesign("lattice");
    const rodfab::voxel::PrinterGrid printerGrid = rodfab::voxel::makePrinterGrid(design, benchVoxel());
    const rodfab::voxel::Rasterizer rasterizer(design, printerGrid);
    const int k0 = printerGrid.dims.z() / 2 / 8 * 8;  // starts on a leaf slab
    return rasterizer.rasterizeLayers(k0, k0 + 400).grid;
  }();
  return *grid;
}
const openvdb::FloatGrid& latticeSlab() {
  static const openvdb::FloatGrid::Ptr grid = [] {
    MappingStats stats;
    return mapToFractions(latticeModulusSlab(), bundledMap(), stats);
  }();
  return *grid;
}

void dither(benchmark::State& state, const openvdb::FloatGrid& grid) {
  const std::string method = ditherMethodNames()[static_cast<std::size_t>(state.range(0))];
  const auto ditherer = makeDitherer(method, {1, nullptr});
  const double cpuBefore = processCpuSeconds();
  for (auto _ : state) benchmark::DoNotOptimize(ditherer->dither(grid));
  state.counters["cpu_ms_per_run"] = 1e3 * (processCpuSeconds() - cpuBefore) / static_cast<double>(state.iterations());
  state.SetLabel(method);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * grid.activeVoxelCount()));
  state.counters["voxels"] = static_cast<double>(grid.activeVoxelCount());
  state.counters["peak_rss_MB"] = peakRssMb();
}

void ditherDenseBlock(benchmark::State& state) { dither(state, denseBlock()); }
void ditherRodBundle(benchmark::State& state) { dither(state, rodBundle()); }
BENCHMARK(ditherDenseBlock)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(ditherRodBundle)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
void ditherLatticeSlab(benchmark::State& state) { dither(state, latticeSlab()); }
BENCHMARK(ditherLatticeSlab)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();

// The lattice slab as `rodfab slice` streams it: one fraction grid per band of 8 layers (a leaf slab,
// as slicer::automaticBandLayers picks for the lattice class's 2000 x 1000 voxel layers), holding the
// band's leaves only, dithered band after band with two outputs alive at a time (the pipeline's two
// bands in flight), so that per-band costs (output trees, leaf allocation) count as in the slicer.
constexpr int kBandLayers = 8;
// `slab` cut into grids of kBandLayers layers (its leaves copied), named `name`.
std::vector<openvdb::FloatGrid::Ptr> slabBands(const openvdb::FloatGrid& slab, const char* name) {
  const openvdb::CoordBBox box = slab.evalActiveVoxelBoundingBox();
  std::vector<openvdb::FloatGrid::Ptr> out;
  for (int k0 = box.min().z(); k0 <= box.max().z(); k0 += kBandLayers) {
    auto band = openvdb::FloatGrid::create(0.0f);
    band->setTransform(slab.transform().copy());
    band->setName(name);
    for (auto leaf = slab.tree().cbeginLeaf(); leaf; ++leaf)
      if (leaf->origin().z() >= k0 && leaf->origin().z() < k0 + kBandLayers)
        band->tree().addLeaf(new openvdb::FloatTree::LeafNodeType(*leaf));
    out.push_back(band);
  }
  return out;
}
const std::vector<openvdb::FloatGrid::Ptr>& latticeSlabBands() {
  static const std::vector<openvdb::FloatGrid::Ptr> bands = slabBands(latticeSlab(), kFractionGridName);
  return bands;
}

void ditherLatticeBands(benchmark::State& state) {
  const std::string method = ditherMethodNames()[static_cast<std::size_t>(state.range(0))];
  const auto ditherer = makeDitherer(method, {1, nullptr});
  const auto& bands = latticeSlabBands();
  const int k0 = bands.front()->evalActiveVoxelBoundingBox().min().z();
  std::int64_t voxels = 0;
  for (const auto& band : bands) voxels += static_cast<std::int64_t>(band->activeVoxelCount());
  const double cpuBefore = processCpuSeconds();
  for (auto _ : state) {
    ditherer->reset();
    openvdb::BoolGrid::Ptr previous, current;
    for (std::size_t b = 0; b < bands.size(); ++b) {
      const int bandK0 = k0 + static_cast<int>(b) * kBandLayers;
      previous = std::move(current);
      current = ditherer->ditherLayers(*bands[b], bandK0, bandK0 + kBandLayers);
      benchmark::DoNotOptimize(current);
    }
  }
  state.SetLabel(method);
  state.SetItemsProcessed(state.iterations() * voxels);
  state.counters["cpu_ms_per_run"] = 1e3 * (processCpuSeconds() - cpuBefore) / static_cast<double>(state.iterations());
  state.counters["voxels"] = static_cast<double>(voxels);
  state.counters["bands"] = static_cast<double>(bands.size());
  state.counters["peak_rss_MB"] = peakRssMb();
}
BENCHMARK(ditherLatticeBands)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();

// The lattice slab's moduli in 8-layer bands, mapped and dithered as `rodfab slice` does it, two
// bands alive: Arg 0 = white, 1 = blue; Arg 1 = 0: mapped into a fraction grid (a recycler keeping 2
// trees, as the slicer's did), then dithered; 1: in one pass (Ditherer::mapAndDitherLayers, no fraction
// grid). cpu_ms_per_run is the process's CPU time a run (every thread).
void mapDitherLatticeBands(benchmark::State& state) {
  const std::string method = ditherMethodNames()[static_cast<std::size_t>(state.range(0))];
  const bool fused = state.range(1) != 0;
  const auto ditherer = makeDitherer(method, {1, nullptr});
  static const std::vector<openvdb::FloatGrid::Ptr> bands = slabBands(latticeModulusSlab(), "modulus_mpa");
  const int k0 = bands.front()->evalActiveVoxelBoundingBox().min().z();
  rodfab::voxel::TreeRecycler<openvdb::FloatTree> fractionTrees(0.0f, 2);
  MappingStats stats;
  const double cpuBefore = processCpuSeconds();
  for (auto _ : state) {
    openvdb::BoolGrid::Ptr previous, current;
    for (std::size_t b = 0; b < bands.size(); ++b) {
      const int bandK0 = k0 + static_cast<int>(b) * kBandLayers, bandK1 = bandK0 + kBandLayers;
      previous = std::move(current);
      current = fused ? ditherer->mapAndDitherLayers(*bands[b], bundledMap(), bandK0, bandK1, stats)
                      : ditherer->ditherLayers(*mapToFractions(*bands[b], bundledMap(), bandK0, bandK1, stats, fractionTrees), bandK0, bandK1);
      benchmark::DoNotOptimize(current);
    }
  }
  state.SetLabel(method + (fused ? " fused" : " map, then dither"));
  state.SetItemsProcessed(static_cast<std::int64_t>(stats.voxels));
  state.counters["cpu_ms_per_run"] = 1e3 * (processCpuSeconds() - cpuBefore) / static_cast<double>(state.iterations());
  state.counters["voxels"] = static_cast<double>(stats.voxels) / static_cast<double>(state.iterations());
  state.counters["peak_rss_MB"] = peakRssMb();
}
BENCHMARK(mapDitherLatticeBands)->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();

// Moduli spanning 2 .. 400 MPa through the bundled calibration's lookup table.
void mapModulusToFraction(benchmark::State& state) {
  static const openvdb::FloatGrid::Ptr modulus = [] {
    auto g = denseBlock().deepCopy();
    for (auto it = g->beginValueOn(); it; ++it) it.setValue(static_cast<float>(2.0 * std::pow(200.0, it.getCoord().x() / 256.0)));
    return g;
  }();
  const auto calibration = rodfab::calibration::loadDefaultCalibration();
  const FractionMap map(calibration);
  MappingStats stats;
  for (auto _ : state) benchmark::DoNotOptimize(mapToFractions(*modulus, map, stats));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * modulus->activeVoxelCount()));
  state.counters["clamped_share"] = static_cast<double>(stats.clamps.total()) / static_cast<double>(stats.voxels);
  state.counters["table_error_bound"] = map.interpolationErrorBound();
  state.counters["peak_rss_MB"] = peakRssMb();
}
BENCHMARK(mapModulusToFraction)->Unit(benchmark::kMillisecond)->UseRealTime();

// The bundled 64 x 32 x 90 mask from scratch (items = mask cells); single-threaded by design. Its
// parameters, voxel included, are the mask file's (BlueNoiseParameters::bundledMask()).
void generateBlueNoiseMask(benchmark::State& state) {
  const BlueNoiseParameters parameters = BlueNoiseParameters::bundledMask();
  for (auto _ : state) benchmark::DoNotOptimize(BlueNoiseMask::generate(parameters));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * 64 * 32 * 90);
  state.counters["peak_rss_MB"] = peakRssMb();
}
BENCHMARK(generateBlueNoiseMask)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
