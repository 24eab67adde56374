// End to end (`rodfab slice` without the command line): design -> voxel bands -> Vero fractions ->
// white-noise dithering -> BMP stacks in a zip, verified. Workloads at the Connex3 voxel:
//   spring6g: the buckling spring scaled to 84.6 x 84.6 x 90 mm (2000 x 1000 x 3000 voxels, 6 gigavoxels;
//             ~0.7 % of them in rods)
//   dense:    a solid block of 84.6 x 84.6 x 9 mm (2000 x 1000 x 300 voxels, every one printed): the
//             worst case for memory
// Arg = TBB thread count. Counters: envelope and active voxels per second, per-stage seconds, peak
// resident memory (process-wide: run one workload per invocation, as scripts/bench.sh does) and
// the job's size. One iteration each: a run takes seconds and writes a job.
#include "calibration/calibration.hpp"
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

double peakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux reports KiB
}

geometry::RodStructure spring6g() { return examples::bucklingSpringScaledTo({84.6, 84.6, 90.0}); }

// One straight rod with a 84.6 x 9 mm rectangular section, 84.6 mm long, flat ends: a solid block.
geometry::RodStructure denseBlock() {
  const geometry::NurbsCurve axis(1, {0, 0, 1, 1}, {geometry::Vec3(0, 42.3, 4.5), geometry::Vec3(84.6, 42.3, 4.5)});
  geometry::RodStructure s;
  s.source = "dense block";
  s.rods.emplace_back("block", axis, geometry::Section::rectangle(84.6, 9.0), geometry::Vec3(0, 1, 0), std::nullopt,
                      geometry::CapStyle::Flat, geometry::BSplineField(1, {0, 0, 1, 1}, {8.0, 190.0}));
  return s;
}

void slice(benchmark::State& state, geometry::RodStructure (*makeDesign)()) {
  openvdb::initialize();
  const geometry::RodStructure design = makeDesign();
  const printer_profiles::Profile profile = printer_profiles::loadProfile("stratasys-objet500-connex3");
  const calibration::Calibration cal = calibration::loadDefaultCalibration();
  const int threads = static_cast<int>(state.range(0));
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("rodfab-bench-slice-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);

  slicer::SliceReport report;
  for (auto _ : state) {
    const auto ditherer = materials::makeDitherer("white", {});
    slicer::SliceSettings settings;
    settings.threads = threads;
    settings.job.output = dir / "job.zip";
    settings.job.force = true;
    report = slicer::sliceDesign(design, profile, cal, *ditherer, settings);
  }
  std::filesystem::remove_all(dir);

  const voxel::PrinterGrid grid = voxel::makePrinterGrid(
      design, openvdb::Vec3d(profile.voxelSizeMm[0], profile.voxelSizeMm[1], profile.voxelSizeMm[2]));
  const double seconds = report.prepareSeconds + report.seconds.source + report.seconds.dither + report.seconds.emit;
  state.counters["envelope_Gvox"] = static_cast<double>(grid.voxelCount()) * 1e-9;
  state.counters["active_Mvox"] = static_cast<double>(report.mapping.voxels) * 1e-6;
  state.counters["envelope_Gvox_per_s"] = static_cast<double>(grid.voxelCount()) * 1e-9 / seconds;
  state.counters["active_Mvox_per_s"] = static_cast<double>(report.mapping.voxels) * 1e-6 / seconds;
  state.counters["s_prepare"] = report.prepareSeconds;
  state.counters["s_voxelize_map"] = report.seconds.source;
  state.counters["s_dither"] = report.seconds.dither;
  state.counters["s_emit"] = report.seconds.emit;
  state.counters["layers"] = report.job.geometry.layers;
  state.counters["job_MB"] = static_cast<double>(report.job.bytes) * 1e-6;
  state.counters["peak_rss_MB"] = peakRssMb();
}

}  // namespace

BENCHMARK_CAPTURE(slice, spring6g, spring6g)->Arg(1)->Arg(2)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK_CAPTURE(slice, dense, denseBlock)->Arg(2)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
