// The slicer library without the command line: automaticBandLayers against its closed form,
// streamJob and sliceDesign into real jobs read back by printer_profiles::inspectJob (its own
// decoder, not the writer's), the same bytes for any band size and thread count, and the coupon
// layout's bars and counts.

#include "slicer_test_support.hpp"

#include "common/stopwatch.hpp"

#include <tbb/parallel_for.h>

using namespace rodfab;
using namespace slicer_test;

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

TEST_CASE("streamJob writes every band's material, the bytes do not depend on the band size") {
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

TEST_CASE("streamJob: bands of whole slabs end on slab boundaries, bands of 4 within a slab, the first one shorter, the same bytes") {
  openvdb::initialize();
  TempDir tmp;
  const openvdb::CoordBBox rigid(openvdb::Coord(0, 0, 3), openvdb::Coord(39, 19, 25));
  const openvdb::CoordBBox rubbery(openvdb::Coord(50, 0, 3), openvdb::Coord(69, 9, 25));
  const openvdb::Vec3d origin(0.5, 0.5, 0.015);
  std::vector<std::string> zips;
  for (const auto& [bandLayers, expected] : {std::pair{8, std::vector<int>{5, 13, 21, 23}}, std::pair{16, std::vector<int>{13, 23}},
                                             std::pair{3, std::vector<int>{3, 6, 9, 12, 15, 18, 21, 23}},
                                             std::pair{4, std::vector<int>{1, 5, 9, 13, 17, 21, 23}}}) {
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
  CHECK(zips[0] == zips[3]);
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
  const auto cpu = [] { return common::cpuClockSeconds(CLOCK_THREAD_CPUTIME_ID); };
  const double end = cpu() + seconds;
  volatile std::uint64_t x = 0;
  while (cpu() < end) x = x + 1;
}

TEST_CASE("streamJob's times: each stage's busy time within the wall time, its CPU time on its arena's threads, the CPU time of every thread") {
  openvdb::initialize();
  TempDir tmp;
  const openvdb::CoordBBox box(openvdb::Coord(0), openvdb::Coord(9, 9, 9));
  const printer_profiles::JobSpec spec = boxJob(box, tmp.path / "job.zip");
  const auto ditherer = materials::makeDitherer("white", {});
  slicer::PipelineOptions options;
  options.bandLayers = 2;  // 5 bands
  const slicer::BandSource boxes = twoBoxes(box, {}, spec.originMm);
  // The source works, a band, two TBB tasks of 30 ms of CPU each (in its arena, on whichever of its
  // threads) and 40 ms on a thread of its own making (outside every arena): it is busy at least 40 ms,
  // its arena's CPU time holds the tasks' 60 ms and not the thread's, and the process's CPU time both.
  const slicer::BandSource slow = [&](int k0, int k1, bool next) {
    tbb::parallel_for(0, 2, [](int) { burnCpu(0.03); });
    std::thread worker([] { burnCpu(0.04); });
    worker.join();
    return boxes(k0, k1, next);
  };
  slicer::StageSeconds seconds;
  {
    // Two threads, as on the machines this runs on: each worker waiting in an arena spins briefly, which
    // the arena's CPU time counts, so the bound below holds for two.
    const tbb::global_control twoThreads(tbb::global_control::max_allowed_parallelism, 2);
    slicer::streamJob(spec, slow, *ditherer, options, seconds);
  }
  CHECK(seconds.source >= 5 * 0.04);
  CHECK(seconds.cpu >= 5 * (0.06 + 0.04));
  for (double busy : {seconds.source, seconds.dither, seconds.emit}) {
    CHECK(busy > 0.0);
    CHECK(busy <= seconds.wall);
  }
  CHECK(seconds.sourceCpu >= 5 * 0.06);
  CHECK(seconds.sourceCpu < 5 * 0.06 + 0.15);  // not the thread's 0.2 s (TBB's workers spin briefly)
  CHECK(seconds.ditherCpu > 0.0);
  CHECK(seconds.emitCpu > 0.0);
  // Every thread's time inside the arenas is part of the process's (1 ms: getrusage's resolution).
  CHECK(seconds.sourceCpu + seconds.ditherCpu + seconds.emitCpu <= seconds.cpu + 0.001);
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
    CHECK(report.mappedWhileDithering);  // white noise maps in its dither stage: the summary says so
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

TEST_CASE("bandEnd: whole slabs end on slab boundaries, sizes dividing a slab on their multiples, others where they reach") {
  CHECK(slicer::bandEnd(3, 8) == 8);
  CHECK(slicer::bandEnd(8, 8) == 16);
  CHECK(slicer::bandEnd(-5, 16) == 8);
  CHECK(slicer::bandEnd(3, 4) == 4);
  CHECK(slicer::bandEnd(4, 4) == 8);
  CHECK(slicer::bandEnd(-3, 4) == 0);
  CHECK(slicer::bandEnd(-8, 2) == -6);
  CHECK(slicer::bandEnd(7, 1) == 8);
  CHECK(slicer::bandEnd(3, 3) == 6);
  const auto slab = [](int k) { return k >= 0 ? k / 8 : -((-k + 7) / 8); };
  for (int k0 = -20; k0 < 20; ++k0)
    for (const int b : {1, 2, 4}) {
      const int end = slicer::bandEnd(k0, b);
      CHECK((end > k0 && end <= k0 + b && slab(end - 1) == slab(k0)));  // never past k0's slab
    }
}
