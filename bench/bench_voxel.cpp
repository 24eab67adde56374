// voxel/: rasterization throughput (items = active voxels) for the 6-gigavoxel scaled buckling spring
// (84.6 x 84.6 x 90 mm: ~2000 x 1000 x 3000 voxels at the default profile's voxel; bench/bench_profile.hpp) and the bundled buckling spring,
// whole design at once and streamed in bands of 64 layers; the piece building (Rasterizer
// construction) on its own. Arg = TBB worker count. Peak resident memory is process-wide: run one
// workload per invocation (--benchmark_filter) to get its own peak; see bench/README.md.
#include "bench/bench_profile.hpp"
#include "common/stopwatch.hpp"
#include "examples/example_designs.hpp"
#include "materials/fraction_map.hpp"
#include "voxel/voxel.hpp"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <malloc.h>
#include <sys/resource.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>

namespace voxel = rodfab::voxel;
namespace examples = rodfab::examples;
namespace materials = rodfab::materials;
namespace calibration = rodfab::calibration;

namespace {

using rodfab::common::processCpuSeconds;

// glibc gives the freed top of a heap back to the system as soon as it exceeds M_TRIM_THRESHOLD
// (128 KiB, raised only by frees of mmapped blocks), so band after band made and freed in turn by
// the same thread page-faulted every band's leaves in afresh: on the lattice (main 49723ca) 366 k
// minor faults and 7.8 CPU s for rasterizing on 1 thread, 2.5 s and 19.5 k faults with the threshold
// raised; those faults made 1-thread runs cost more CPU than 2-thread ones. `rodfab slice`, whose
// pipeline holds several bands at once, took 49 k faults for the whole lattice job either way. The
// benchmarks keep freed memory for reuse, so they time the rasterizer and the mapping, not the kernel.
[[maybe_unused]] const int keepFreedMemory = [] { return mallopt(M_TRIM_THRESHOLD, 1 << 30); }();

double peakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux reports KiB
}

struct Workload {
  rodfab::geometry::RodStructure structure;
  voxel::PrinterGrid grid;
};

Workload makeWorkload(rodfab::geometry::RodStructure structure) {
  openvdb::initialize();
  Workload w{std::move(structure), {}};
  w.grid = voxel::makePrinterGrid(w.structure, rodfab::bench::benchVoxelMm());  // the benchmark profile's voxel
  return w;
}

// 312 rods of 1.2 mm diameter filling 84.6 x 84.6 x 90 mm.
const Workload& largeSpring() {
  static const Workload w = makeWorkload(examples::bucklingSpringScaledTo({84.6, 84.6, 90.0}));
  return w;
}

// The bundled buckling spring (radius 15 mm, height 32 mm, 0.8 mm rods).
const Workload& smallSpring() {
  static const Workload w = makeWorkload(examples::bucklingSpring());
  return w;
}

// The benchmark classes (examples::benchmarkDesign), each built once per process.
const Workload& benchmarkClass(const std::string& name) {
  static std::mutex mutex;
  static std::map<std::string, std::unique_ptr<Workload>> made;
  const std::lock_guard<std::mutex> lock(mutex);
  auto& w = made[name];
  if (!w) w = std::make_unique<Workload>(makeWorkload(examples::benchmarkDesign(name)));
  return *w;
}

std::string envelopeLabel(const voxel::PrinterGrid& g) {
  return std::to_string(g.dims.x()) + "x" + std::to_string(g.dims.y()) + "x" + std::to_string(g.dims.z());
}

constexpr int kBandLayers = 64;  // layers per band in the streaming variant

// Per-iteration totals -> counters. items/s = active voxels per second (real time).
void report(benchmark::State& state, const Workload& w, std::uint64_t active, std::uint64_t exact) {
  const double envelope = static_cast<double>(w.grid.voxelCount());
  const auto iterations = static_cast<double>(state.iterations());
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(active));
  state.counters["envelope_vox_per_s"] = benchmark::Counter(iterations * envelope, benchmark::Counter::kIsRate);
  state.counters["active_voxels"] = static_cast<double>(active);
  state.counters["envelope_voxels"] = envelope;
  state.counters["fill_share"] = static_cast<double>(active) / envelope;
  // Voxels sent to the exact test, per active voxel.
  state.counters["exact_share"] = active > 0 ? static_cast<double>(exact) / static_cast<double>(active) : 0.0;
  state.counters["peak_rss_MiB"] = peakRssMb();
  state.SetLabel(envelopeLabel(w.grid));
}

// Rasterizer construction: every rod cut into pieces with measured error bounds.
void buildPieces(benchmark::State& state, const Workload& w) {
  const voxel::RasterOptions options{static_cast<int>(state.range(0))};
  std::size_t pieces = 0;
  for (auto _ : state) {
    voxel::Rasterizer rasterizer(w.structure, w.grid, options);
    pieces = rasterizer.pieceCount();
    benchmark::DoNotOptimize(pieces);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * w.structure.rods.size()));  // rods
  state.counters["rods"] = static_cast<double>(w.structure.rods.size());
  state.counters["pieces"] = static_cast<double>(pieces);
  state.counters["peak_rss_MiB"] = peakRssMb();
}

std::uint64_t activeVoxels(const voxel::Rasterization& r) {
  std::uint64_t n = 0;
  for (std::uint64_t v : r.voxelsPerRod) n += v;  // every active voxel is won by exactly one rod
  return n;
}

// On the first iteration only, untimed: the grid holds as many active voxels as the rods won.
void verify(benchmark::State& state, const voxel::Rasterization& r, std::uint64_t active) {
  state.PauseTiming();
  if (r.grid->activeVoxelCount() != active) state.SkipWithError("active voxel count differs from the rods' tally");
  state.ResumeTiming();
}

// The whole design into one grid; the timing includes freeing the grid at the end of each iteration.
void rasterizeWhole(benchmark::State& state, const Workload& w) {
  const voxel::Rasterizer rasterizer(w.structure, w.grid, {static_cast<int>(state.range(0))});
  std::uint64_t active = 0, exact = 0;
  bool first = true;
  for (auto _ : state) {
    const voxel::Rasterization r = rasterizer.rasterize();
    active = activeVoxels(r);
    exact = r.exactEvaluations;
    if (first) verify(state, r, active);
    first = false;
  }
  report(state, w, active, exact);
}

// Bands of kBandLayers layers, each band's grid freed before the next (how the slicer streams), timed
// including the frees.
void rasterizeBands(benchmark::State& state, const Workload& w) {
  const voxel::Rasterizer rasterizer(w.structure, w.grid, {static_cast<int>(state.range(0))});
  std::uint64_t active = 0, exact = 0, bandMax = 0;
  bool first = true;
  for (auto _ : state) {
    active = exact = bandMax = 0;
    for (int z = 0; z < w.grid.dims.z(); z += kBandLayers) {
      const voxel::Rasterization r = rasterizer.rasterizeLayers(z, z + kBandLayers);
      const std::uint64_t n = activeVoxels(r);
      active += n;
      exact += r.exactEvaluations;
      bandMax = std::max(bandMax, n);
      if (first) verify(state, r, n);
    }
    first = false;
  }
  report(state, w, active, exact);
  state.counters["bands"] = static_cast<double>((w.grid.dims.z() + kBandLayers - 1) / kBandLayers);
  state.counters["band_max_active"] = static_cast<double>(bandMax);
}

// Bands as the slicer makes them for a 2000 x 1000 footprint (slicer::automaticBandLayers: ~32 M
// envelope voxels a band), and either the rasterization alone or followed by the modulus-to-fraction
// mapping (materials::mapToFractions, bundled calibration), as `rodfab slice`'s "voxelize + map" does.
constexpr int kSliceBandLayers = 16;
void rasterizeClass(benchmark::State& state, const std::string& name, bool map) {
  const Workload& w = benchmarkClass(name);
  const voxel::Rasterizer rasterizer(w.structure, w.grid, {static_cast<int>(state.range(0))});
  const materials::FractionMap fractionMap(calibration::loadDefaultCalibration());
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(state.range(0)));
  voxel::TreeRecycler<openvdb::FloatTree> fractionTrees(0.0f);  // as `rodfab slice` streams its bands
  std::uint64_t active = 0, exact = 0;
  bool first = true;
  const double cpu0 = processCpuSeconds();
  for (auto _ : state) {
    active = exact = 0;
    for (int z = 0; z < w.grid.dims.z(); z += kSliceBandLayers) {
      const voxel::Rasterization r = rasterizer.rasterizeLayers(z, z + kSliceBandLayers);
      const std::uint64_t n = activeVoxels(r);
      active += n;
      exact += r.exactEvaluations;
      if (first) verify(state, r, n);
      if (map) {
        materials::MappingStats stats;
        const openvdb::FloatGrid::Ptr fractions = materials::mapToFractions(*r.grid, fractionMap, z, z + kSliceBandLayers, stats, fractionTrees);
        benchmark::DoNotOptimize(fractions.get());
        if (first && stats.voxels != n) state.SkipWithError("mapping lost voxels");
      }
    }
    first = false;
  }
  const double cpu = processCpuSeconds() - cpu0;
  report(state, w, active, exact);
  state.counters["cpu_s_per_iter"] = cpu / static_cast<double>(state.iterations());
  state.counters["active_Mvox_per_cpu_s"] = 1e-6 * static_cast<double>(active) * static_cast<double>(state.iterations()) / cpu;
}
void classBuildPieces(benchmark::State& state, const std::string& name) { buildPieces(state, benchmarkClass(name)); }
void classRasterize(benchmark::State& state, const std::string& name) { rasterizeClass(state, name, false); }
void classRasterizeMap(benchmark::State& state, const std::string& name) { rasterizeClass(state, name, true); }
#define RODFAB_CLASS_BENCHMARKS(id, name)                                                                                           \
  BENCHMARK_CAPTURE(classBuildPieces, id, name)->ArgName("threads")->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1); \
  BENCHMARK_CAPTURE(classRasterize, id, name)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1); \
  BENCHMARK_CAPTURE(classRasterizeMap, id, name)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1)
RODFAB_CLASS_BENCHMARKS(spring, "spring");
RODFAB_CLASS_BENCHMARKS(lattice, "lattice");
RODFAB_CLASS_BENCHMARKS(curved_lattice, "curved-lattice");
RODFAB_CLASS_BENCHMARKS(dense, "dense");

// Workload 1: the 6-gigavoxel design (the targets: >= 100 M active voxels/s, < 1 GiB peak).
void largeBuildPieces(benchmark::State& state) { buildPieces(state, largeSpring()); }
void largeRasterize(benchmark::State& state) { rasterizeWhole(state, largeSpring()); }
void largeRasterizeBands(benchmark::State& state) { rasterizeBands(state, largeSpring()); }
BENCHMARK(largeBuildPieces)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);
BENCHMARK(largeRasterize)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(2);
BENCHMARK(largeRasterizeBands)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(2);

// Workload 2: the bundled buckling spring.
void smallBuildPieces(benchmark::State& state) { buildPieces(state, smallSpring()); }
void smallRasterize(benchmark::State& state) { rasterizeWhole(state, smallSpring()); }
void smallRasterizeBands(benchmark::State& state) { rasterizeBands(state, smallSpring()); }
BENCHMARK(smallBuildPieces)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);
BENCHMARK(smallRasterize)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);
BENCHMARK(smallRasterizeBands)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

}  // namespace
