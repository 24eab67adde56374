// The slicer library without the command line: automaticBandLayers against its closed form,
// streamJob and sliceDesign into real jobs read back by printer_profiles::inspectJob (its own
// decoder, not the writer's), the same bytes for any band size and thread count, and the coupon
// layout's bars and counts.
#include "calibration/calibration_file.hpp"
#include "common/memory_budget.hpp"
#include "geometry/design_file.hpp"
#include "geometry/rod.hpp"
#include "materials/materials.hpp"
#include "printer_profiles/inspect.hpp"
#include "printer_profiles/job_writer.hpp"
#include "printer_profiles/profile.hpp"
#include "slicer/coupon_layout.hpp"
#include "slicer/job_pipeline.hpp"
#include "slicer/slice_design.hpp"
#include "voxel/diagnostics.hpp"
#include "voxel/printer_grid.hpp"
#include "voxel/rasterize.hpp"

#include <catch2/catch.hpp>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <thread>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

using namespace rodfab;
namespace fs = std::filesystem;

namespace {

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("rodfab-test-slicer-" + std::to_string(::getpid()) + "-" + std::to_string(counter()++));
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
  static int& counter() {
    static int n = 0;
    return n;
  }
};

std::string fileBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

const printer_profiles::Profile& connex3() {
  static const printer_profiles::Profile p = printer_profiles::loadProfile("stratasys-objet500-connex3");
  return p;
}

std::uint64_t inspectedVoxels(const printer_profiles::InspectReport& r, printer_profiles::MaterialRole role) {
  std::uint64_t n = 0;
  for (const auto& m : r.materials) n += m.role == role ? m.voxels : 0;
  return n;
}

// Fraction 1 in box `rigid`, 0 in box `rubbery`, for the layers a band asks for.
slicer::BandSource twoBoxes(const openvdb::CoordBBox& rigid, const openvdb::CoordBBox& rubbery, const openvdb::Vec3d& originMm) {
  return [=](int k0, int k1, bool withNext) {
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName(materials::kFractionGridName);
    grid->setTransform(voxel::printerTransform(connex3().voxelSize(), originMm));
    for (auto [box, value] : {std::pair{rigid, 1.0f}, std::pair{rubbery, 0.0f}}) {
      box.min().z() = std::max(box.min().z(), k0);
      box.max().z() = std::min(box.max().z(), k1 - 1 + (withNext ? 1 : 0));
      if (!box.empty()) grid->tree().denseFill(box, value, true);
    }
    return slicer::BandGrids{grid, nullptr};
  };
}

// A job of part `box` at the origin the box tests use, written to `output`.
printer_profiles::JobSpec boxJob(const openvdb::CoordBBox& box, const fs::path& output) {
  printer_profiles::JobSpec spec;
  spec.profile = connex3();
  spec.partBounds = box;
  spec.originMm = openvdb::Vec3d(0.5, 0.5, 0.015);
  spec.options.output = output;
  return spec;
}

// Lowers the soft data limit for the scope: the default memory budget follows it (80 %,
// common/memory_budget.hpp) as under `ulimit -d`. The hard limit stays, so the soft one comes back;
// a lower limit the test runs under is kept (never raised past it).
struct SoftDataLimit {
  rlimit saved{};
  explicit SoftDataLimit(std::uint64_t bytes) {
    REQUIRE(::getrlimit(RLIMIT_DATA, &saved) == 0);
    rlimit lowered = saved;
    lowered.rlim_cur = std::min(rlim_t(bytes), saved.rlim_cur);  // rlim_cur <= rlim_max; RLIM_INFINITY is the largest
    REQUIRE(::setrlimit(RLIMIT_DATA, &lowered) == 0);
  }
  ~SoftDataLimit() { ::setrlimit(RLIMIT_DATA, &saved); }
};

// The message of the common::OutOfMemory sliceDesign refuses `design` with (the test fails if it does not).
std::string memoryRefusal(const geometry::RodStructure& design, const calibration::Calibration& cal, materials::Ditherer& ditherer,
                          const slicer::SliceSettings& settings) {
  try {
    slicer::sliceDesign(design, connex3(), cal, ditherer, settings);
  } catch (const common::OutOfMemory& e) {
    return e.what();
  }
  FAIL("expected OutOfMemory");
  return {};
}

}  // namespace

TEST_CASE("automaticBandLayers is 21 Mi voxels over the layer's voxels in whole 8-layer slabs, 8 to 64") {
  const auto part = [](int w, int h) { return openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(w - 1, h - 1, 99)); };
  CHECK(slicer::automaticBandLayers(part(100, 100)) == 64);    // 10^4 voxels a layer: 275 slabs, capped at 8
  CHECK(slicer::automaticBandLayers(part(1024, 1024)) == 16);  // 2^20: 22020096 / 2^23 = 2.6 slabs
  CHECK(slicer::automaticBandLayers(part(4096, 2048)) == 8);   // 2^23 voxels a layer: 0.33 slabs, at least 1
  CHECK(slicer::automaticBandLayers(part(2000, 1000)) == 8);   // the dense benchmark block: 1.38 slabs
  CHECK(slicer::automaticBandLayers(part(11000, 4600)) == 8);  // 5.06e7: below one slab, at least 1
  CHECK(slicer::automaticBandLayers(part(672, 512)) == 64);    // 344064 = 21 Mi / 64: exactly 8 slabs
  CHECK(slicer::automaticBandLayers(part(673, 512)) == 56);    // one column more: 7.99 slabs
}

TEST_CASE("streamJob writes every band's material; the bytes do not depend on the band size") {
  openvdb::initialize();
  TempDir tmp;
  const openvdb::CoordBBox rigid(openvdb::Coord(0, 0, 0), openvdb::Coord(39, 19, 22));
  const openvdb::CoordBBox rubbery(openvdb::Coord(50, 0, 0), openvdb::Coord(69, 9, 22));
  std::vector<std::string> zips;
  for (int bandLayers : {64, 5, 1}) {
    for (const char* method : {"white", "error-diffusion"}) {
      const fs::path folder = tmp.path / (std::string(method) + std::to_string(bandLayers));
      fs::create_directories(folder);
      const printer_profiles::JobSpec spec = boxJob(openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(69, 19, 22)), folder / "job.zip");
      const auto ditherer = materials::makeDitherer(method, {});
      slicer::PipelineOptions options;
      options.bandLayers = bandLayers;
      std::vector<int> done;
      options.onBand = [&](int d, int total) {
        CHECK(total == 23);
        done.push_back(d);
      };
      slicer::StageSeconds seconds;
      const printer_profiles::JobResult job = slicer::streamJob(spec, twoBoxes(rigid, rubbery, spec.originMm), *ditherer, options, seconds);
      REQUIRE(done.size() == static_cast<std::size_t>((23 + bandLayers - 1) / bandLayers));
      CHECK(done.back() == 23);
      CHECK(std::is_sorted(done.begin(), done.end()));
      const printer_profiles::InspectReport report = printer_profiles::inspectJob(job.path);
      INFO((report.defects.empty() ? std::string() : report.defects.front()));
      REQUIRE(report.ok());
      CHECK(report.layers == 23);
      // Fractions 1 and 0 are exact for every ditherer: all rigid, all rubbery.
      CHECK(inspectedVoxels(report, printer_profiles::MaterialRole::Rigid) == static_cast<std::uint64_t>(rigid.volume()));
      CHECK(inspectedVoxels(report, printer_profiles::MaterialRole::Rubbery) == static_cast<std::uint64_t>(rubbery.volume()));
      zips.push_back(fileBytes(job.path));
    }
  }
  // Same ditherer, other band sizes: the same bytes (zips[0,2,4] white, [1,3,5] error diffusion).
  CHECK(zips[0] == zips[2]);
  CHECK(zips[0] == zips[4]);
  CHECK(zips[1] == zips[3]);
  CHECK(zips[1] == zips[5]);
}

TEST_CASE("streamJob: bands of whole slabs end on slab boundaries, the first one shorter; the same bytes") {
  openvdb::initialize();
  TempDir tmp;
  const openvdb::CoordBBox rigid(openvdb::Coord(0, 0, 3), openvdb::Coord(39, 19, 25));
  const openvdb::CoordBBox rubbery(openvdb::Coord(50, 0, 3), openvdb::Coord(69, 9, 25));
  const openvdb::Vec3d origin(0.5, 0.5, 0.015);
  std::vector<std::string> zips;
  for (const auto& [bandLayers, expected] : {std::pair{8, std::vector<int>{5, 13, 21, 23}}, std::pair{16, std::vector<int>{13, 23}},
                                             std::pair{3, std::vector<int>{3, 6, 9, 12, 15, 18, 21, 23}}}) {
    INFO(bandLayers << " layers a band");
    printer_profiles::JobSpec spec;
    spec.profile = connex3();
    spec.partBounds = openvdb::CoordBBox(openvdb::Coord(0, 0, 3), openvdb::Coord(69, 19, 25));  // starts off a slab
    spec.originMm = origin;
    fs::create_directories(tmp.path / std::to_string(bandLayers));
    spec.options.output = tmp.path / std::to_string(bandLayers) / "job.zip";  // the manifest names the file
    slicer::PipelineOptions options;
    options.bandLayers = bandLayers;
    std::vector<int> done;
    options.onBand = [&](int d, int) { done.push_back(d); };
    slicer::StageSeconds seconds;
    const auto ditherer = materials::makeDitherer("error-diffusion", {});
    const printer_profiles::JobResult job = slicer::streamJob(spec, twoBoxes(rigid, rubbery, origin), *ditherer, options, seconds);
    CHECK(done == expected);
    zips.push_back(fileBytes(job.path));
  }
  CHECK(zips[0] == zips[1]);
  CHECK(zips[0] == zips[2]);
}

TEST_CASE("streamJob: an onBand that throws leaves no job and nothing staged") {
  openvdb::initialize();
  TempDir tmp;
  const openvdb::CoordBBox box(openvdb::Coord(0), openvdb::Coord(9, 9, 29));
  const printer_profiles::JobSpec spec = boxJob(box, tmp.path / "job.zip");
  const auto ditherer = materials::makeDitherer("white", {});
  slicer::PipelineOptions options;
  options.bandLayers = 4;
  options.onBand = [](int done, int) {
    if (done >= 8) throw std::runtime_error("stop");
  };
  slicer::StageSeconds seconds;
  CHECK_THROWS_WITH(slicer::streamJob(spec, twoBoxes(box, {}, spec.originMm), *ditherer, options, seconds), "stop");
  CHECK(fs::is_empty(tmp.path));
  options.bandLayers = 0;
  CHECK_THROWS_AS(slicer::streamJob(spec, twoBoxes(box, {}, spec.originMm), *ditherer, options, seconds), std::invalid_argument);
}

TEST_CASE("streamJob: a source that throws while later stages hold earlier bands leaves no job and nothing staged") {
  openvdb::initialize();
  TempDir tmp;
  const openvdb::CoordBBox box(openvdb::Coord(0), openvdb::Coord(9, 9, 29));
  const printer_profiles::JobSpec spec = boxJob(box, tmp.path / "job.zip");
  const auto ditherer = materials::makeDitherer("error-diffusion", {});
  slicer::PipelineOptions options;
  options.bandLayers = 3;
  int written = 0;
  options.onBand = [&](int, int) { ++written; };
  const slicer::BandSource boxes = twoBoxes(box, {}, spec.originMm);
  const slicer::BandSource failing = [&](int k0, int k1, bool next) {
    if (k0 >= 15) throw std::runtime_error("source failed");
    return boxes(k0, k1, next);
  };
  slicer::StageSeconds seconds;
  CHECK_THROWS_WITH(slicer::streamJob(spec, failing, *ditherer, options, seconds), "source failed");
  CHECK(written <= 5);  // bands [0, 15) at most
  CHECK(fs::is_empty(tmp.path));
  CHECK(seconds.wall > 0.0);
}

// Busy-waits until this thread has used `seconds` of CPU time.
static void burnCpu(double seconds) {
  const auto cpu = [] {
    timespec t{};
    ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
  };
  const double end = cpu() + seconds;
  volatile std::uint64_t x = 0;
  while (cpu() < end) x = x + 1;
}

TEST_CASE("streamJob's times: each stage's busy time within the wall time, the CPU time of every thread") {
  openvdb::initialize();
  TempDir tmp;
  const openvdb::CoordBBox box(openvdb::Coord(0), openvdb::Coord(9, 9, 9));
  const printer_profiles::JobSpec spec = boxJob(box, tmp.path / "job.zip");
  const auto ditherer = materials::makeDitherer("white", {});
  slicer::PipelineOptions options;
  options.bandLayers = 2;  // 5 bands
  const slicer::BandSource boxes = twoBoxes(box, {}, spec.originMm);
  // The source works 40 ms of CPU a band, on a thread of its own: it is busy at least that long,
  // and the process's CPU time includes it (a thread of the source's making is one of every thread).
  const slicer::BandSource slow = [&](int k0, int k1, bool next) {
    std::thread worker([] { burnCpu(0.04); });
    worker.join();
    return boxes(k0, k1, next);
  };
  slicer::StageSeconds seconds;
  slicer::streamJob(spec, slow, *ditherer, options, seconds);
  CHECK(seconds.source >= 5 * 0.04);
  CHECK(seconds.cpu >= 5 * 0.04);
  for (double busy : {seconds.source, seconds.dither, seconds.emit}) {
    CHECK(busy > 0.0);
    CHECK(busy <= seconds.wall);
  }
  // Times add to what the caller gave: a second job adds its own.
  const slicer::StageSeconds first = seconds;
  fs::remove(tmp.path / "job.zip");
  slicer::streamJob(spec, slow, *ditherer, options, seconds);
  CHECK(seconds.source >= first.source + 5 * 0.04);
  CHECK(seconds.wall > first.wall);
}

TEST_CASE("sliceDesign: a straight rod's voxels are its volume, every one in the job, for any band size and thread count") {
  openvdb::initialize();
  TempDir tmp;
  const double radius = 0.6, length = 5.0;
  const geometry::NurbsCurve axis(1, {0, 0, 1, 1}, {{0, 0, 0}, {length, 0, 0}});
  const calibration::Calibration cal = calibration::loadDefaultCalibration();
  // E from twice the floor to half the stiffest mix along the rod: both materials, nothing clamped.
  geometry::Rod rod("rod", axis, geometry::Section::circle(2 * radius), std::nullopt, std::nullopt, geometry::CapStyle::Flat,
                    geometry::BSplineField(1, {0, 0, 1, 1}, {2 * cal.floorMpa(), 0.5 * cal.maxModulusMpa()}));
  const geometry::RodStructure design{"test", {rod}};
  std::vector<std::string> zips;
  for (auto [threads, bandLayers] : {std::pair{0, 0}, std::pair{1, 7}, std::pair{2, 1}}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads > 0 ? threads : 64);
    const fs::path folder = tmp.path / ("t" + std::to_string(threads) + "b" + std::to_string(bandLayers));
    fs::create_directories(folder);
    slicer::SliceSettings settings;
    settings.designFile = "rod.json";
    settings.threads = threads;
    settings.bandLayers = bandLayers;
    settings.job.output = folder / "rod.zip";
    const auto ditherer = materials::makeDitherer("white", {});
    const slicer::SliceReport report = slicer::sliceDesign(design, connex3(), cal, *ditherer, settings);
    REQUIRE(report.voxelsPerRod.size() == 1);
    CHECK(report.voxelsPerRod[0] == report.mapping.voxels);
    const std::array<double, 3>& v = connex3().voxelSizeMm;
    const double volume = std::numbers::pi * radius * radius * length;
    CHECK(double(report.mapping.voxels) * v[0] * v[1] * v[2] == Approx(volume).epsilon(0.03));
    CHECK(report.mapping.clamps.total() == 0);
    const printer_profiles::InspectReport inspected = printer_profiles::inspectJob(report.job.path);
    INFO((inspected.defects.empty() ? std::string() : inspected.defects.front()));
    REQUIRE(inspected.ok());
    CHECK(inspectedVoxels(inspected, printer_profiles::MaterialRole::Rigid) +
              inspectedVoxels(inspected, printer_profiles::MaterialRole::Rubbery) ==
          report.mapping.voxels);
    CHECK(std::abs(inspected.layers - 2 * radius / v[2]) <= 1.0);  // the rod's diameter in layers
    zips.push_back(fileBytes(report.job.path));
  }
  CHECK(zips[0] == zips[1]);
  CHECK(zips[0] == zips[2]);
}

TEST_CASE("the coupon layout: bars of whole voxels, balanced rows, each voxel counted in its own bar") {
  openvdb::initialize();
  const printer_profiles::Profile& p = connex3();
  const slicer::CouponVoxels sizes = slicer::couponVoxels(p, {30, 5, 1.5}, 5);
  CHECK(sizes.bar == openvdb::Coord(std::lround(30 / p.voxelSizeMm[0]), std::lround(5 / p.voxelSizeMm[1]), 50));
  CHECK(sizes.gapI == std::lround(5 / p.voxelSizeMm[0]));
  CHECK_THROWS_WITH(slicer::couponVoxels(p, {30, 5, 0.01}, 5), Catch::Contains("--size") && Catch::Contains("along z"));
  CHECK_THROWS_WITH(slicer::couponVoxels(p, {30, 5, 1}, 0.01), Catch::Contains("--gap"));
  CHECK_THROWS_WITH(slicer::couponVoxels(p, {600, 5, 1}, 5), Catch::Contains("too large by") && Catch::Contains("along x"));

  // 30 bars of 30 mm: a 490 mm tray takes 14 a row with 5 mm gaps (14 * 35 - 5 = 485), so 3 rows of 10.
  const slicer::CouponLayout layout = slicer::planCouponLayout(p, 30, sizes);
  CHECK(layout.rows == 3);
  CHECK(layout.perRow == 10);
  for (std::size_t n = 0; n < layout.bars.size(); ++n) {
    const openvdb::CoordBBox& b = layout.bars[n];
    CHECK(layout.barAt(b.min().x(), b.min().y()) == static_cast<int>(n));
    CHECK(layout.barAt(b.max().x(), b.max().y()) == static_cast<int>(n));
    CHECK(layout.barAt(b.max().x() + 1, b.min().y()) == -1);  // the gap after it
    CHECK(layout.bounds.isInside(b));
  }
  CHECK(layout.barAt(layout.bars[0].min().x(), layout.bars[0].min().y()) == 0);
  CHECK(layout.bars[0].min().y() > layout.bars[layout.bars.size() - 1].min().y());  // bar 0 in the top row

  // Fractions 0 and 1 through the counting ditherer: every voxel counted once, Vero exactly where 1.
  const slicer::CouponLayout two = slicer::planCouponLayout(p, 2, slicer::couponVoxels(p, {3, 1, 0.3}, 1));
  const std::vector<double> fractions = {0.0, 1.0};
  const auto white = materials::makeDitherer("white", {});
  slicer::BarCountingDitherer counting(*white, two);
  const slicer::BandSource bands = slicer::couponBands(two, fractions, p, openvdb::Vec3d(0.02, 0.04, 0.015));
  counting.reset();
  counting.ditherLayers(*bands(0, two.bar.z(), false).fraction, 0, two.bar.z());
  CHECK(counting.voxels()[0] == static_cast<std::uint64_t>(two.bars[0].volume()));
  CHECK(counting.voxels()[1] == static_cast<std::uint64_t>(two.bars[1].volume()));
  CHECK(counting.vero()[0] == 0);
  CHECK(counting.vero()[1] == counting.voxels()[1]);
  const nlohmann::json bars = slicer::couponBarsJson(two, fractions, counting, 0, p.voxelSizeMm);
  CHECK(bars[1]["vero_share"].get<double>() == 1.0);
  CHECK(bars[0]["specimen"] == "coupon-00");
}

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
  CHECK(slots >= 2 * 80.0 * layerVoxels);   // at least two slots of ~82 bytes a voxel (materials/README.md)
  CHECK(slots <= 8 * 100.0 * layerVoxels);  // and not the whole tray's layer: at most 4 workers + 3 slots
}

TEST_CASE("sliceDesign refuses a slice over the memory budget before any band, writing nothing; the message says what to change") {
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
  CHECK_THAT(memoryRefusal(design, cal, *ditherer, settings), Catch::Contains("plate.json") && Catch::Contains("bands of 64 layers") &&
                                                                 Catch::Contains("--band-layers") && Catch::Contains("--max-memory"));
  CHECK(fs::is_empty(tmp.path));  // no job, nothing staged
}

TEST_CASE("the memory check passes the bundled examples under a 2 GiB cap, with the estimate above their real needs") {
  // Resident peaks of `rodfab slice EXAMPLE --threads 2` (automatic bands, /usr/bin/time, 2026-12-03; the
  // larger of white and error diffusion): the estimate must stay above them.
  const std::vector<std::pair<const char*, double>> measuredPeakMb{{"arm-cast", 197.5}, {"buckling-spring", 156.2},
                                                                   {"unfolding-box", 223.7}};
  openvdb::initialize();
  const SoftDataLimit limit(std::uint64_t{2} << 30);
  for (const auto& [name, peakMb] : measuredPeakMb) {
    INFO(name);
    const geometry::RodStructure design = geometry::readDesign(fs::path("examples") / (std::string(name) + ".json"));
    const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, connex3().voxelSize());
    const voxel::Rasterizer rasterizer(design, grid);
    const int automatic = slicer::automaticBandLayers(slicer::designVoxelBounds(design, grid));
    const std::uint64_t writer = slicer::jobWriterBytes(connex3(), slicer::designVoxelBounds(design, grid), 16);
    for (const char* name : {"white", "error-diffusion"}) {
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
    return slicer::sliceMemoryBytes(design, grid, bandLayers, *ditherer, concurrency, writer, rasterizer.pieceCount());
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
  CHECK_THAT(memoryRefusal(design, cal, *ditherer, settings), Catch::Contains("plate.json") &&
                                                                 Catch::Contains("the smallest of the band sizes tried") &&
                                                                 Catch::Contains("--max-memory") && !Catch::Contains("--band-layers"));
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

TEST_CASE("the memory estimate of single rods: layer voxels and band leaves at or above the grid's, within 3 times",
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
    double bandLeaves = 0.0;
    for (int k0 = 0; k0 < grid.dims.z(); k0 += kBandLayers)
      bandLeaves = std::max(bandLeaves, double(rasterizer.rasterizeLayers(k0, std::min(grid.dims.z(), k0 + kBandLayers + 1)).grid->tree().leafCount()));
    const voxel::RasterEstimate e = voxel::estimateRaster(design, grid, kBandLayers);
    CAPTURE(layerVoxels, e.layerVoxels, bandLeaves, e.bandLeaves);
    REQUIRE(layerVoxels > 500);
    CHECK(e.layerVoxels >= layerVoxels);
    CHECK(e.layerVoxels <= 3.0 * layerVoxels);
    CHECK(e.bandLeaves >= bandLeaves);
    CHECK(e.bandLeaves <= 3.0 * bandLeaves);
  }
}
