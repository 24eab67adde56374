// The job writer alone on the benchmark classes (issue 17's "emit >= 2 GB/s of layer bitmaps on 2
// cores"): classEmit/CLASS/threads:N times JobWriter::addBand for every band of the class and finalize()
// (verification on), as `rodfab slice` calls them, with nothing else competing for the cores. The bands
// are made once per process, outside the timing, the way `rodfab slice` makes them: the rasterizer, the
// default calibration's fraction map, white noise with seed 7, the slicer's automatic band size
// (slicer::automaticBandLayers; bands end on 8-layer slabs as streamJob cuts them), each band's
// dithered material grid kept in memory (a BoolGrid: the lattice's 269 M voxels in a few hundred MB).
// The modulus grids `rodfab slice` also hands the writer (for the modulus previews: the top view looks
// up the modulus of every pixel a layer newly claims) are kept only by classEmitModulus/CLASS: as
// FloatGrids they take 0.4 GB for the spring, 2.1 GB for the lattice. Not included: the job report
// (report.html, slicer/job_report.hpp), which `rodfab slice` renders inside finalize().
// Counters: layer_bitmap_GB_per_s (the layer BMPs' bytes, counted as bench_slice's figures are: images x
// their BMP size, over the writer's wall time), cpu_s (process user + system in the writer's calls),
// s_bands and cpu_s_bands (the writer's start and addBand), s_finalize and cpu_s_finalize,
// grids_MB (the class's kept grids, OpenVDB's memUsage), peak_rss_MB (process-wide, the bands included: run one
// workload per process, as scripts/bench.sh does), job_MB.
#include "bench/bench_fixtures.hpp"
#include "bench/bench_profile.hpp"
#include "common/stopwatch.hpp"
#include "calibration/calibration.hpp"
#include "common/local_time_zone.hpp"
#include "examples/example_designs.hpp"
#include "materials/fraction_map.hpp"
#include "materials/materials.hpp"
#include "printer_profiles/printer_profiles.hpp"
#include "slicer/job_pipeline.hpp"
#include "slicer/slice_design.hpp"
#include "voxel/voxel.hpp"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace fs = std::filesystem;
namespace pp = rodfab::printer_profiles;
using namespace rodfab;

namespace {

// As rodfab's main does, before Google Benchmark's main starts a thread (common/local_time_zone.hpp).
[[maybe_unused]] const bool kLocalTimeZoneKept = (rodfab::common::keepLocalTimeZone(), true);

using rodfab::common::processCpuSeconds;

constexpr std::uint64_t kSeed = 7;  // a fixed seed, so every run emits the same bands

// A class's job as the writer is given it: its spec (without the output), its dithered material grid
// and (optionally) its modulus grid, each whole, and the bands' layers and leaves. One grid a class, not
// one a band: a band's tree holds the internal nodes over its whole footprint for its 8 layers (~4 MB a
// band of the lattice, 1.3 GB for its 376 bands), a class's shares them between its bands.
template <typename GridT>
using LeafList = std::vector<const typename GridT::TreeType::LeafNodeType*>;

struct BandLeaves {
  int k0 = 0, k1 = 0;
  LeafList<openvdb::BoolGrid> material;
  LeafList<openvdb::FloatGrid> modulus;
};

struct ClassGrids {
  pp::JobSpec spec;
  openvdb::BoolGrid::Ptr material;
  openvdb::FloatGrid::Ptr modulus;  // null unless kept
  std::vector<BandLeaves> bands;
  int bandLayers = 0;
};

// Adds band grid `part`'s leaves to `whole` (made on first use, with part's transform and name).
template <typename GridT>
void gather(typename GridT::Ptr& whole, GridT& part) {
  part.tree().voxelizeActiveTiles();
  if (!whole) whole = part.copyWithNewTree();
  whole->tree().merge(part.tree());
}

// Files every leaf of `grid` under the band holding its layers (bands are whole slabs, so one band
// holds all of a leaf's voxels).
template <typename GridT>
void fileLeaves(const GridT& grid, std::vector<BandLeaves>& bands, LeafList<GridT> BandLeaves::*list) {
  for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) {
    const int z = std::max(leaf->origin().z(), bands.front().k0);
    const auto band = std::upper_bound(bands.begin(), bands.end(), z, [](int k, const BandLeaves& b) { return k < b.k0; }) - 1;
    ((*band).*list).push_back(leaf.getLeaf());
  }
}

// A band's grid of the class's leaves: what the slicer's pipeline hands the writer for that band.
template <typename GridT>
typename GridT::Ptr bandGrid(const GridT& whole, const LeafList<GridT>& leaves) {
  const typename GridT::Ptr band = whole.copyWithNewTree();
  for (const auto* leaf : leaves) band->tree().addLeaf(new typename GridT::TreeType::LeafNodeType(*leaf));
  return band;
}

ClassGrids makeClassGrids(const std::string& name, bool keepModulus) {
  openvdb::initialize();
  const geometry::RodStructure design = examples::benchmarkDesign(name);
  const pp::Profile& profile = rodfab::bench::benchProfile();
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, profile.voxelSize());
  ClassGrids c;
  c.spec.profile = profile;
  c.spec.partBounds = slicer::designVoxelBounds(design, grid);
  c.spec.originMm = grid.origin;
  c.spec.metadata.design = name + ".json";
  c.spec.metadata.ditherer = "white-noise";
  c.spec.metadata.seed = kSeed;
  c.bandLayers = slicer::automaticBandLayers(c.spec.partBounds);

  const voxel::Rasterizer rasterizer(design, grid, {0});
  const materials::FractionMap fractionMap(calibration::loadDefaultCalibration());
  const auto ditherer = materials::makeDitherer("white", materials::DitherOptions(kSeed));
  materials::MappingStats stats;
  const int kLast = c.spec.partBounds.max().z();
  for (int k0 = c.spec.partBounds.min().z(); k0 <= kLast;) {
    const int k1 = std::min(kLast + 1, slicer::bandEnd(k0, c.bandLayers));
    const voxel::Rasterization ras = rasterizer.rasterizeLayers(k0, k1);
    gather(c.material, *ditherer->ditherLayers(*materials::mapToFractions(*ras.grid, fractionMap, k0, k1, stats), k0, k1));
    if (keepModulus) gather(c.modulus, *ras.grid);
    c.bands.push_back({k0, k1, {}, {}});
    k0 = k1;
  }
  fileLeaves(*c.material, c.bands, &BandLeaves::material);
  if (c.modulus) fileLeaves(*c.modulus, c.bands, &BandLeaves::modulus);
  return c;
}

// Each class made once per process (one workload per process keeps the peak RSS its own).
const ClassGrids& classGrids(const std::string& name, bool keepModulus) {
  static std::map<std::pair<std::string, bool>, std::unique_ptr<ClassGrids>> made;
  auto& c = made[{name, keepModulus}];
  if (!c) c = std::make_unique<ClassGrids>(makeClassGrids(name, keepModulus));
  return *c;
}

// The layer images' bytes: one BMP per layer and emitted material (the model materials; support too
// when the policy is explicit), each the size of a 1-bit BMP of the job's images.
double layerBitmapBytes(const pp::JobWriter& writer, const pp::Profile& profile) {
  const pp::JobGeometry& g = writer.geometry();
  int stacks = 0;
  for (const pp::ProfileMaterial& m : profile.materials)
    stacks += m.role != pp::MaterialRole::Support || writer.supportPolicy() == pp::SupportPolicy::Explicit;
  const double imageBytes = double(pp::Bitmap::inBmpFile(g.width, g.height, profile.xDpi, profile.yDpi).bmpFile().size());
  return imageBytes * g.layers * stacks;
}

void emitClass(benchmark::State& state, const std::string& name, bool keepModulus) {
  const ClassGrids& c = classGrids(name, keepModulus);
  const fs::path dir = fs::temp_directory_path() / ("rodfab-bench-emit-class-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(state.range(0)));
  pp::JobSpec spec = c.spec;
  spec.options.output = dir / "job.zip";
  spec.options.force = true;
  double bitmapBytes = 0.0, jobBytes = 0.0;
  // Wall and process CPU seconds of the writer's calls: [0] its start and the bands, [1] finalize().
  double wall[2] = {0.0, 0.0}, cpu[2] = {0.0, 0.0};
  // Only the writer's calls are timed: a band's grid is cut from the class's between them, while no
  // writer work runs (addBand returns once the band is staged).
  const auto timed = [&](int part, const auto& work) {
    const double cpu0 = processCpuSeconds();
    const auto t0 = std::chrono::steady_clock::now();
    work();
    wall[part] += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    cpu[part] += processCpuSeconds() - cpu0;
  };
  for (auto _ : state) {
    const double before = wall[0] + wall[1];
    std::optional<pp::JobWriter> writer;
    timed(0, [&] { writer.emplace(spec); });
    for (const BandLeaves& b : c.bands) {
      // The band's grids are held here and freed after the writer's call, untimed: in `slice` they go back
      // to the ditherer's and rasterizer's recyclers, not to the heap (freed inside addBand, the bands'
      // trees cost the lattice's writer 0.57 of its 1.94 s of band CPU).
      const auto material = bandGrid(*c.material, b.material);
      const auto modulus = c.modulus ? bandGrid(*c.modulus, b.modulus) : nullptr;
      timed(0, [&] { writer->addBand(pp::LayerBand{material, modulus, b.k0, b.k1}); });
    }
    timed(1, [&] { jobBytes = double(writer->finalize().bytes); });
    bitmapBytes = layerBitmapBytes(*writer, spec.profile);
    state.SetIterationTime(wall[0] + wall[1] - before);
  }
  fs::remove_all(dir);
  const double iterations = double(state.iterations());
  state.counters["layer_bitmap_GB_per_s"] = benchmark::Counter(bitmapBytes * 1e-9 * iterations, benchmark::Counter::kIsRate);
  state.counters["layer_bitmap_GB"] = bitmapBytes * 1e-9;
  state.counters["cpu_s"] = (cpu[0] + cpu[1]) / iterations;
  state.counters["s_bands"] = wall[0] / iterations;
  state.counters["cpu_s_bands"] = cpu[0] / iterations;
  state.counters["s_finalize"] = wall[1] / iterations;
  state.counters["cpu_s_finalize"] = cpu[1] / iterations;
  state.counters["bands"] = double(c.bands.size());
  state.counters["band_layers"] = c.bandLayers;
  state.counters["grids_MB"] = double(c.material->memUsage() + (c.modulus ? c.modulus->memUsage() : 0)) * 1e-6;
  state.counters["job_MB"] = jobBytes * 1e-6;
  state.counters["peak_rss_MB"] = rodfab::bench::peakRssMb();
}

// classEmit/CLASS/threads:N and classEmitModulus/CLASS/threads:N, CLASS as bench_slice spells it.
[[maybe_unused]] const bool registered = [] {
  for (const std::string name : {"spring", "lattice", "curved-lattice", "dense"})
    for (const bool keepModulus : {false, true}) {
      std::string id = name;
      std::replace(id.begin(), id.end(), '-', '_');
      benchmark::RegisterBenchmark(((keepModulus ? "classEmitModulus/" : "classEmit/") + id).c_str(),
                                   [=](benchmark::State& state) { emitClass(state, name, keepModulus); })
          ->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kSecond)->UseManualTime()->Iterations(1);
    }
  return true;
}();

}  // namespace
