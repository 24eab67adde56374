// materials/: dither-quality metrics against hand-built truth and the ditherers measured by them.
#include "materials/materials.hpp"
#include "tests/materials_fixture.hpp"

#include <catch2/catch.hpp>

#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <vector>

using namespace rodfab::materials;
using rodfab::test::kTestVoxel;

namespace {


std::size_t countVero(const openvdb::BoolGrid& g) {
  std::size_t n = 0;
  for (auto it = g.cbeginValueOn(); it; ++it) n += *it ? 1 : 0;
  return n;
}

// Expected low-pass RMS of independent coin flips with probability f over a whole box: at voxel x the
// filtered error is a weighted mean of independent errors of variance f (1 - f), so its variance is
// f (1 - f) sum w^2 / (sum w)^2; the Gaussian separates, so both sums are products over the axes.
double whiteNoiseLowPassRms(const openvdb::Coord& size, double f, const openvdb::Vec3d& voxelMm, double sigmaMm) {
  std::array<std::vector<double>, 3> ratio;
  for (int a = 0; a < 3; ++a) {
    const double sigma = sigmaMm / voxelMm[a];
    const int radius = static_cast<int>(std::ceil(4.0 * sigma));
    for (int x = 0; x < size[a]; ++x) {
      double s1 = 0, s2 = 0;
      for (int y = std::max(0, x - radius); y <= std::min(size[a] - 1, x + radius); ++y) {
        const double w = std::exp(-0.5 * (y - x) * (y - x) / (sigma * sigma));
        s1 += w;
        s2 += w * w;
      }
      ratio[a].push_back(s2 / (s1 * s1));
    }
  }
  // The mean over the box of a product of per-axis terms is the product of per-axis means.
  double mean = f * (1 - f);
  for (int a = 0; a < 3; ++a) mean *= std::accumulate(ratio[a].begin(), ratio[a].end(), 0.0) / size[a];
  return std::sqrt(mean);
}

}  // namespace


TEST_CASE("materials: dither quality: metrics against hand-built truth", "[materials][quality]") {
  // A constant error: every voxel asks for 0.25 and gets Tango; the normalized low-pass keeps it at
  // exactly -0.25 everywhere, boundaries included.
  const auto rod = makeRod(0.6, 2.0, 1, 0.25f, kTestVoxel);
  auto tango = openvdb::BoolGrid::create(false);
  tango->setTransform(rod->transform().copy());
  tango->tree().topologyUnion(rod->tree());
  CHECK(lowPassErrorRms(*rod, *tango, 0.1) == Approx(0.25).epsilon(1e-9));
  const DitherQuality q = measureDitherQuality(*rod, *tango);
  CHECK(q.meanBias == Approx(-0.25));
  CHECK(q.veroVoxels == 0);
  CHECK(q.largestVeroClusterShare == 0.0);

  // Two Vero slabs (x < 3 and x >= 6) in a 10^3 block: the larger holds 4/7 of the Vero voxels.
  // Runs along x per line: Vero 3, Tango 3, Vero 4 -> mean 10/3; along y and z one run per line.
  const auto block = makeUniformBlock(openvdb::Coord(10, 10, 10), 0.5f, kTestVoxel);
  auto slabs = openvdb::BoolGrid::create(false);
  slabs->setTransform(block->transform().copy());
  for (auto it = block->cbeginValueOn(); it; ++it) {
    const int x = it.getCoord().x();
    slabs->tree().setValueOn(it.getCoord(), x < 3 || x >= 6);
  }
  const DitherQuality s = measureDitherQuality(*block, *slabs);
  CHECK(s.largestVeroClusterShare == Approx(4.0 / 7.0));
  CHECK(s.meanRunLength[0] == Approx(10.0 / 3.0));
  CHECK(s.meanRunLength[1] == Approx(10.0));
  CHECK(s.meanRunLength[2] == Approx(10.0));
  CHECK(s.achievedMean == Approx(0.7));

  // Different regions are refused.
  slabs->tree().setValueOff(openvdb::Coord(1, 1, 1));
  CHECK_THROWS_WITH(measureDitherQuality(*block, *slabs), Catch::Contains("(1, 1, 1)"));
}

TEST_CASE("materials: dither quality on a 128 x 64 x 180 block at 0.3: white vs blue vs error diffusion", "[materials][quality]") {
  const openvdb::Coord size(128, 64, 180);
  const double f = 0.3;
  const auto block = makeUniformBlock(size, static_cast<float>(f), kTestVoxel);
  const DitherQuality white = measureDitherQuality(*block, *makeDitherer("white", {1, nullptr})->dither(*block));
  const DitherQuality blue = measureDitherQuality(*block, *makeDitherer("blue", {1, nullptr})->dither(*block));
  const DitherQuality ed = measureDitherQuality(*block, *makeDitherer("error-diffusion", {1, nullptr})->dither(*block));

  // White noise is independent coin flips: its low-pass error and run lengths have closed forms.
  CHECK(white.lowPassRms100um == Approx(whiteNoiseLowPassRms(size, f, kTestVoxel, 0.1)).epsilon(0.05));
  CHECK(white.lowPassRms250um == Approx(whiteNoiseLowPassRms(size, f, kTestVoxel, 0.25)).epsilon(0.08));
  CHECK(white.lowPassRms100um == Approx(0.022).epsilon(0.1));  // the published figure
  for (int a = 0; a < 3; ++a) {
    // A line of L voxels has 1 + (L - 1) 2 f (1 - f) runs on average.
    const double runsPerLine = 1 + (size[a] - 1) * 2 * f * (1 - f);
    CHECK(white.meanRunLength[a] == Approx(size[a] / runsPerLine).epsilon(0.01));
  }
  CHECK(std::abs(white.meanBias) < 0.002);

  CHECK(blue.lowPassRms100um < white.lowPassRms100um / 5);
  CHECK(ed.lowPassRms100um < white.lowPassRms100um / 5);
  CHECK(blue.lowPassRms100um < 0.004);
  CHECK(ed.lowPassRms100um < 0.004);
  CHECK(blue.lowPassRms250um < white.lowPassRms250um / 5);
  CHECK(ed.lowPassRms250um < white.lowPassRms250um / 5);
  CHECK(std::abs(blue.meanBias) < 1e-4);
  CHECK(std::abs(ed.meanBias) < 1e-4);
}

TEST_CASE("materials: a 1 mm rod at 0.3 keeps its mean with every ditherer, along every axis", "[materials][quality]") {
  for (int axis = 0; axis < 3; ++axis) {
    const auto rod = makeRod(1.0, 20.0, axis, 0.3f, kTestVoxel);
    // The rod's volume in voxels, within the staircase error of its boundary.
    const double voxelVolume = kTestVoxel[0] * kTestVoxel[1] * kTestVoxel[2];
    CHECK(static_cast<double>(rod->activeVoxelCount()) ==
          Approx(std::numbers::pi * 0.25 * 20.0 / voxelVolume).epsilon(0.03));
    for (const std::string& method : ditherMethodNames()) {
      INFO(method << " along axis " << axis);
      const auto material = makeDitherer(method, {9, nullptr})->dither(*rod);
      const double share = static_cast<double>(countVero(*material)) / static_cast<double>(rod->activeVoxelCount());
      CHECK(std::abs(share - 0.3) < 0.005);
    }
  }
  const auto rod = makeRod(1.0, 10.0, 0, 0.3f, kTestVoxel);
  const double white = lowPassErrorRms(*rod, *makeDitherer("white", {1, nullptr})->dither(*rod), 0.1);
  for (const char* method : {"blue", "error-diffusion"}) {
    INFO(method);
    CHECK(lowPassErrorRms(*rod, *makeDitherer(method, {1, nullptr})->dither(*rod), 0.1) < white / 5);
  }
}

TEST_CASE("materials: sample regions reject bad parameters", "[materials][quality]") {
  CHECK_THROWS_AS(makeUniformBlock(openvdb::Coord(0, 1, 1), 0.5f, kTestVoxel), std::invalid_argument);
  CHECK_THROWS_AS(makeUniformBlock(openvdb::Coord(1, 1, 1), 1.5f, kTestVoxel), std::invalid_argument);
  CHECK_THROWS_AS(makeRod(1.0, 1.0, 3, 0.5f, kTestVoxel), std::invalid_argument);
  CHECK_THROWS_AS(makeRod(-1.0, 1.0, 0, 0.5f, kTestVoxel), std::invalid_argument);
}
