// printer_profiles/: layer encoding and whole-job throughput (bitmaps, PNG/BMP, zip, verification).
#include "bench/bench_profile.hpp"
#include "common/sha256.hpp"
#include "common/xxh128.hpp"
#include "printer_profiles/deflate.hpp"
#include "printer_profiles/printer_profiles.hpp"
#include "voxel/printer_grid.hpp"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <unistd.h>

#include <cmath>
#include <random>

namespace pp = rodfab::printer_profiles;
namespace fs = std::filesystem;

namespace {

// The printer of bench/bench_profile.hpp ($RODFAB_BENCH_PROFILE, default the bundled default profile).
const pp::Profile& profile() { return rodfab::bench::benchProfile(); }

// A layer of a rod lattice: ~8% of the pixels set, in runs, like a sliced rod structure.
pp::Bitmap latticeLayer(int width, int height) {
  pp::Bitmap b(width, height);
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c)
      if ((c % 200) < 24 || (r % 100) < 6) b.set(c, r, ((c * 7 + r * 13) % 5) < 2);
  return b;
}

void BM_EncodeBmp(benchmark::State& state) {
  const pp::Bitmap b = latticeLayer(2048, 1024);
  for (auto _ : state) benchmark::DoNotOptimize(pp::encodeBmp(b, profile().xDpi, profile().yDpi));
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(b.stride() * static_cast<std::size_t>(b.height())));
}
BENCHMARK(BM_EncodeBmp)->Unit(benchmark::kMicrosecond);

void BM_EncodePng1(benchmark::State& state) {
  const pp::Bitmap b = latticeLayer(2048, 1024);
  for (auto _ : state) benchmark::DoNotOptimize(pp::encodePng1(b, profile().xDpi, profile().yDpi));
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(b.stride() * static_cast<std::size_t>(b.height())));
}
BENCHMARK(BM_EncodePng1)->Unit(benchmark::kMicrosecond);

// Raw deflate of one layer BMP at each igzip level (printer_profiles/deflate.hpp; the README's table).
void BM_DeflateLayer(benchmark::State& state) {
  const pp::Bytes bmp = pp::encodeBmp(latticeLayer(2048, 1024), profile().xDpi, profile().yDpi);
  std::size_t compressed = 0;
  for (auto _ : state) compressed = pp::deflateBytes(bmp, static_cast<int>(state.range(0)), pp::DeflateWrapper::Raw).size();
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(bmp.size()));
  state.counters["ratio"] = static_cast<double>(bmp.size()) / static_cast<double>(compressed);
}
BENCHMARK(BM_DeflateLayer)->DenseRange(0, 3)->Unit(benchmark::kMicrosecond);

// The manifest's checksum of one layer image: SHA-256 (the job's until 2026-12-02) and XXH3-128 (since).
void BM_Sha256(benchmark::State& state) {
  const pp::Bytes bmp = pp::encodeBmp(latticeLayer(2048, 1024), profile().xDpi, profile().yDpi);
  for (auto _ : state) benchmark::DoNotOptimize(rodfab::common::sha256Hex(bmp));
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(bmp.size()));
}
BENCHMARK(BM_Sha256)->Unit(benchmark::kMicrosecond);

void BM_Xxh128(benchmark::State& state) {
  const pp::Bytes bmp = pp::encodeBmp(latticeLayer(2048, 1024), profile().xDpi, profile().yDpi);
  for (auto _ : state) benchmark::DoNotOptimize(rodfab::common::xxh128Hex(bmp));
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(bmp.size()));
}
BENCHMARK(BM_Xxh128)->Unit(benchmark::kMicrosecond);

// Rods along x and y through a 20 x 20 x 3 mm block, white-noise Vero/Tango: ~470 x 236 px x 100 layers.
openvdb::BoolGrid::Ptr rodLattice() {
  openvdb::initialize();
  auto grid = openvdb::BoolGrid::create(false);
  grid->setTransform(rodfab::voxel::printerTransform(profile().voxelSize(), openvdb::Vec3d(0, 0, 0)));
  auto acc = grid->getAccessor();
  std::mt19937 rng(5);
  std::bernoulli_distribution vero(0.45);
  const auto& v = profile().voxelSizeMm;
  const double radius = 0.7;
  for (int k = 0; k < 100; ++k)
    for (int j = 0; j < 236; ++j)
      for (int i = 0; i < 472; ++i) {
        const double x = i * v[0], y = j * v[1], z = k * v[2];
        const double dy = std::fmod(y, 4.0) - 2.0, dx = std::fmod(x, 4.0) - 2.0, dz = z - 1.5;
        if (dy * dy + dz * dz < radius * radius || dx * dx + dz * dz < radius * radius) acc.setValueOn({i, j, k}, vero(rng));
      }
  return grid;
}

// The lattice cut into bands of 16 layers, as the slicer hands them over (built once, outside the timing).
struct Bands {
  openvdb::CoordBBox box;
  std::vector<pp::LayerBand> bands;
  openvdb::Index64 voxels = 0;
};
const Bands& latticeBands() {
  static const Bands cached = [] {
    const openvdb::BoolGrid::Ptr grid = rodLattice();
    Bands b;
    b.box = grid->evalActiveVoxelBoundingBox();
    b.voxels = grid->activeVoxelCount();
    for (int k = b.box.min().z(); k <= b.box.max().z(); k += 16) {
      const int end = std::min(k + 16, b.box.max().z() + 1);
      auto band = openvdb::BoolGrid::create(false);
      band->setTransform(grid->transform().copy());
      auto acc = band->getAccessor();
      for (auto it = grid->cbeginValueOn(); it; ++it)
        if (it.getCoord().z() >= k && it.getCoord().z() < end) acc.setValueOn(it.getCoord(), *it);
      b.bands.push_back({band, nullptr, k, end});
    }
    return b;
  }();
  return cached;
}

// A whole zip job at a given thread count; second argument 1 = verify by re-reading before the rename.
void BM_WriteJob(benchmark::State& state) {
  const Bands& lattice = latticeBands();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(state.range(0)));
  const fs::path dir = fs::temp_directory_path() / ("rodfab-bench-job-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::uintmax_t bytes = 0;
  double bitmapBytes = 0;  // of the layer bitmaps the job holds (rigid and rubbery; support is the printer's)
  for (auto _ : state) {
    pp::JobSpec spec;
    spec.profile = profile();
    spec.partBounds = lattice.box;
    spec.originMm = openvdb::Vec3d(0, 0, 0);
    spec.options.output = dir / "job.zip";
    spec.options.force = true;
    spec.options.verify = state.range(1) != 0;
    pp::JobWriter writer(spec);
    const pp::JobGeometry& g = writer.geometry();
    bitmapBytes = 2.0 * ((g.width + 7) / 8) * g.height * g.layers;
    for (const pp::LayerBand& band : lattice.bands) writer.addBand(band);
    bytes = writer.finalize().bytes;
  }
  fs::remove_all(dir);
  state.counters["voxels/s"] = benchmark::Counter(static_cast<double>(lattice.voxels) * state.iterations(),
                                                  benchmark::Counter::kIsRate);
  state.counters["layers/s"] = benchmark::Counter(static_cast<double>(lattice.box.dim().z()) * state.iterations(),
                                                  benchmark::Counter::kIsRate);
  state.counters["zip_MB"] = static_cast<double>(bytes) / 1e6;
  state.counters["bitmap_bytes/s"] = benchmark::Counter(bitmapBytes * static_cast<double>(state.iterations()),
                                                        benchmark::Counter::kIsRate, benchmark::Counter::kIs1000);
}
BENCHMARK(BM_WriteJob)->Args({1, 0})->Args({2, 0})->Args({2, 1})->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
