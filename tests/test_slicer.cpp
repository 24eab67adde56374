// slicer/: the progress line's rate and its end, and the job report's map of clamped moduli against a brute-force
// count over the same voxels.
#include "slicer/job_report.hpp"
#include "slicer/progress.hpp"

#include <catch2/catch.hpp>

#include <sstream>

using namespace rodfab;

TEST_CASE("progress shows no rate before a second has passed, then the true one") {
  std::ostringstream out;
  const auto t0 = cli::Progress::Clock::now();
  const cli::Progress progress("layers", 200, cli::Progress::Mode::Lines, out);
  const std::string early = progress.status(50, t0 + std::chrono::milliseconds(1));
  CHECK(early == "50/200 layers (25%)");
  const std::string later = progress.status(100, t0 + std::chrono::seconds(2));
  CHECK(later.find("100/200 layers (50%), 50 layers/s, 2 s left") == 0);
}

TEST_CASE("progress stopped before the end claims nothing done, finished, it says done") {
  for (const auto mode : {cli::Progress::Mode::Lines, cli::Progress::Mode::Bar}) {
    std::ostringstream out;
    cli::Progress progress("layers", 3000, mode, out);
    progress.update(7, cli::Progress::Clock::now() + std::chrono::seconds(1));  // past the bar's redraw interval
    progress.stop();
    progress.finish();  // after stop: nothing more
    CHECK(out.str().find("7/3000 layers") != std::string::npos);
    CHECK(out.str().find("done") == std::string::npos);
    REQUIRE_FALSE(out.str().empty());
    CHECK(out.str().back() == '\n');  // an error message that follows starts on its own line
  }
  std::ostringstream out;
  cli::Progress progress("layers", 3000, cli::Progress::Mode::Lines, out);
  progress.update(3000);
  progress.finish();
  CHECK(out.str().find("done: 3000 layers") != std::string::npos);
}

TEST_CASE("the clamp map counts what the fraction map clamps, voxels and tiles, within the band and part") {
  openvdb::initialize();
  const double floor = 8.0, max = 190.0;
  const openvdb::CoordBBox part(openvdb::Coord(-5, -3, 0), openvdb::Coord(40, 20, 30));
  auto grid = openvdb::FloatGrid::create(0.0f);
  auto acc = grid->getAccessor();
  // Voxels below, at, inside and above the range, NaN, and one outside the part.
  const float values[] = {1.0f, 8.0f, 50.0f, 190.0f, 190.5f, 400.0f, std::numeric_limits<float>::quiet_NaN(), 7.9f};
  int n = 0;
  for (int k = 0; k < 31; ++k)
    for (int i = -5; i < 10; ++i) acc.setValue(openvdb::Coord(i, (i + k) % 7, k), values[n++ % 8]);
  acc.setValue(openvdb::Coord(100, 0, 3), 1.0f);  // outside the part box: ignored
  grid->tree().addTile(1, openvdb::Coord(16, 8, 8), 500.0f, true);  // an 8^3 tile above the maximum, k 8..15

  const int k0 = 4, k1 = 12;
  slicer::ClampMap map(part, {0.0423, 0.0846, 0.03}, floor, max);
  map.add(*grid, k0, k1);
  std::uint64_t below = 0, above = 0;
  for (auto it = grid->cbeginValueOn(); it; ++it) {
    openvdb::CoordBBox box;
    it.getBoundingBox(box);
    for (auto c = box.beginXYZ(); c; ++c) {
      const openvdb::Coord x = *c;
      if (x.z() < k0 || x.z() >= k1 || !part.isInside(x)) continue;
      below += !(*it >= floor);
      above += *it > max;
    }
  }
  CHECK(below > 0);
  CHECK(above > 8 * 8 * 4);  // the tile's part inside the band
  CHECK(map.belowFloor() == below);
  CHECK(map.aboveMax() == above);
  map.addOutline(*grid);  // the outline counts nothing
  CHECK(map.belowFloor() == below);
  CHECK(map.aboveMax() == above);
  const printer_profiles::Bytes png = map.renderPng();
  REQUIRE(png.size() > 8);
  CHECK(png[1] == 'P');
  CHECK(png[2] == 'N');
}

TEST_CASE("a large part is binned to at most kMaxBins a side") {
  const openvdb::CoordBBox part(openvdb::Coord(0, 0, 0), openvdb::Coord(11582, 4608, 6665));
  slicer::ClampMap map(part, {0.0423, 0.0846, 0.03}, 8.0, 190.0);
  CHECK((11583 + map.binVoxels() - 1) / map.binVoxels() <= slicer::ClampMap::kMaxBins);
  CHECK(map.binVoxels() == (11583 + slicer::ClampMap::kMaxBins - 1) / slicer::ClampMap::kMaxBins);
}

// The band's grid as the rasterizer makes it: the voxels of layers [k0, k1) only.
openvdb::FloatGrid::Ptr bandOf(const openvdb::FloatGrid& whole, int k0, int k1) {
  auto band = openvdb::FloatGrid::create(0.0f);
  auto acc = band->getAccessor();
  for (auto it = whole.cbeginValueOn(); it; ++it) {
    openvdb::CoordBBox box;
    it.getBoundingBox(box);
    for (auto c = box.beginXYZ(); c; ++c)
      if ((*c).z() >= k0 && (*c).z() < k1) acc.setValue(*c, *it);
  }
  return band;
}

TEST_CASE("the clamp map's picture is the same whatever the bands, with and without clamps in them") {
  openvdb::initialize();
  // Bins of one voxel (a small part), so every voxel a leaf lacks would show: voxels in a few layers of
  // each leaf, clamped ones (above 190 MPa) in layers 9 and 21 only, so some bands draw through add()
  // and others through addOutline(), as the slicer calls them.
  const openvdb::CoordBBox part(openvdb::Coord(0, 0, 0), openvdb::Coord(30, 12, 39));
  auto whole = openvdb::FloatGrid::create(0.0f);
  auto acc = whole->getAccessor();
  for (int k = 0; k < 40; k += 3)
    for (int i = k % 5; i < 27; i += 2) acc.setValue(openvdb::Coord(i, (i * 7 + k) % 13, k), k == 9 || k == 21 ? 300.0f : 60.0f);
  const auto picture = [&](int bandLayers) {
    slicer::ClampMap map(part, {0.0423, 0.0846, 0.03}, 8.0, 190.0);
    for (int k0 = 0; k0 < 40; k0 += bandLayers) {
      const int k1 = std::min(40, k0 + bandLayers);
      const auto band = bandOf(*whole, k0, k1);
      const bool clamped = (k0 <= 9 && 9 < k1) || (k0 <= 21 && 21 < k1);
      if (clamped) map.add(*band, k0, k1);
      else map.addOutline(*band);
    }
    CHECK(map.aboveMax() == 12 + 13);  // layer 9: i = 4, 6, .., 26; layer 21: i = 1, 3, .., 25
    return map.renderPng();
  };
  const printer_profiles::Bytes reference = picture(40);
  for (const int bandLayers : {1, 3, 5, 8, 16}) {
    INFO("bands of " << bandLayers << " layers");
    CHECK(picture(bandLayers) == reference);
  }
}

