// End to end (`rodfab slice` without the command line): design -> voxel bands -> Vero fractions ->
// dithering -> BMP stacks in a zip, verified, for the benchmark profile (bench_profile.hpp). The
// benchmark classes of examples::benchmarkDesign (rodfab_generate_examples --benchmark CLASS FILE writes
// each as a design file), in voxels of the default profile (Connex3):
//   spring:         the buckling spring scaled to 84.6 x 84.6 x 90 mm (2000 x 1000 x 3000 voxels, 6
//                   gigavoxels; 43 M of them in 312 curved rods)
//   lattice:        1,520 straight rods joined at 8 x 8 x 9 nodes in the same envelope (269 M printed)
//   curved-lattice: the same rods bowed sideways (271 M printed)
//   dense:          a solid block of 84.6 x 84.6 x 9 mm (2000 x 1000 x 300 voxels, every one printed): the
//                   worst case for memory
// Named slice/CLASS_DITHERER/threads: white, blue and error-diffusion for each class.
// Arg = TBB thread count. Counters: envelope and active voxels per second, per-stage seconds, peak
// resident memory (process-wide: run one workload per invocation, as scripts/bench.sh does) and
// the job's size. One iteration each: a run takes seconds and writes a job.
#include "bench/bench_profile.hpp"
#include "calibration/calibration.hpp"
#include "common/local_time_zone.hpp"
#include "examples/example_designs.hpp"
#include "materials/materials.hpp"
#include "printer_profiles/printer_profiles.hpp"
#include "slicer/slice_design.hpp"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <sys/resource.h>
#include <unistd.h>

#include <filesystem>
#include <string>

using namespace rodfab;

namespace {

// As rodfab's main does, before Google Benchmark's main starts a thread (common/local_time_zone.hpp).
[[maybe_unused]] const bool kLocalTimeZoneKept = (rodfab::common::keepLocalTimeZone(), true);

double peakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux reports KiB
}

void slice(benchmark::State& state, const char* designClass, const char* method) {
  openvdb::initialize();
  const geometry::RodStructure design = examples::benchmarkDesign(designClass);
  const printer_profiles::Profile& profile = rodfab::bench::benchProfile();
  const calibration::Calibration cal = calibration::loadDefaultCalibration();
  const int threads = static_cast<int>(state.range(0));
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("rodfab-bench-slice-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);

  slicer::SliceReport report;
  rusage before{};
  getrusage(RUSAGE_SELF, &before);
  for (auto _ : state) {
    const auto ditherer = materials::makeDitherer(method, {});
    slicer::SliceSettings settings;
    settings.threads = threads;
    settings.job.output = dir / "job.zip";
    settings.job.force = true;
    report = slicer::sliceDesign(design, profile, cal, *ditherer, settings);
  }
  rusage after{};
  getrusage(RUSAGE_SELF, &after);
  std::filesystem::remove_all(dir);
  const auto toSeconds = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec); };
  // Process CPU time (user + sys, every thread): the figure that holds on a loaded machine.
  state.counters["cpu_s"] = toSeconds(after.ru_utime) - toSeconds(before.ru_utime) + toSeconds(after.ru_stime) - toSeconds(before.ru_stime);

  const voxel::PrinterGrid grid = voxel::makePrinterGrid(
      design, profile.voxelSize());
  const double seconds = report.prepareSeconds + report.seconds.wall;
  state.counters["envelope_Gvox"] = static_cast<double>(grid.voxelCount()) * 1e-9;
  state.counters["active_Mvox"] = static_cast<double>(report.mapping.voxels) * 1e-6;
  state.counters["envelope_Gvox_per_s"] = static_cast<double>(grid.voxelCount()) * 1e-9 / seconds;
  state.counters["active_Mvox_per_s"] = static_cast<double>(report.mapping.voxels) * 1e-6 / seconds;
  state.counters["s_prepare"] = report.prepareSeconds;
  state.counters["s_bands"] = report.seconds.wall;  // wall: the stages overlap
  // Wall, overlapping (job_pipeline.hpp). White and blue map the moduli in the dither stage, error
  // diffusion in the source's (SliceReport::mappedWhileDithering).
  state.counters["busy_s_voxelize"] = report.seconds.source;
  state.counters["voxelize_Mvox_per_s"] = static_cast<double>(report.mapping.voxels) * 1e-6 / report.seconds.source;
  state.counters["busy_s_dither"] = report.seconds.dither;
  state.counters["busy_s_emit"] = report.seconds.emit;
  state.counters["cpu_s_bands"] = report.seconds.cpu;  // the process, every thread
  // CPU inside each stage's arena (StageSeconds::sourceCpu ...), and the voxelize stage's rate per CPU
  // second of it times the threads: what it gets done on the cores it is given inside slice, comparable
  // with the rasterizer alone (bench_voxel's classRasterize, wall on that many threads).
  state.counters["cpu_s_voxelize"] = report.seconds.sourceCpu;
  state.counters["cpu_s_dither"] = report.seconds.ditherCpu;
  state.counters["cpu_s_emit"] = report.seconds.emitCpu;
  if (report.seconds.sourceCpu > 0)
    state.counters["voxelize_Mvox_per_cpu_s_x_threads"] =
        static_cast<double>(report.mapping.voxels) * 1e-6 / report.seconds.sourceCpu * static_cast<double>(threads);
  state.counters["layers"] = report.job.geometry.layers;
  state.counters["job_MB"] = static_cast<double>(report.job.bytes) * 1e-6;
  state.counters["peak_rss_MB"] = peakRssMb();
  state.counters["estimate_MB"] = static_cast<double>(report.memoryEstimateBytes) * 1e-6;  // slicer::sliceMemoryBytes
}

}  // namespace

#define RODFAB_SLICE(id, designClass)                                                                              \
  BENCHMARK_CAPTURE(slice, id##_white, designClass, "white")->Arg(2)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime(); \
  BENCHMARK_CAPTURE(slice, id##_blue, designClass, "blue")->Arg(2)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();   \
  BENCHMARK_CAPTURE(slice, id##_error_diffusion, designClass, "error-diffusion")->Arg(2)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime()
RODFAB_SLICE(spring, "spring");
RODFAB_SLICE(lattice, "lattice");
RODFAB_SLICE(curved_lattice, "curved-lattice");
RODFAB_SLICE(dense, "dense");
// One thread, for the scaling (the spring only).
BENCHMARK_CAPTURE(slice, spring_white, "spring", "white")->Arg(1)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
