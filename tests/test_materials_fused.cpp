// Mapping and dithering in one pass (Ditherer::mapAndDitherLayers) against map-then-dither, bit for bit.
#include "geometry/geometry.hpp"
#include "materials/materials.hpp"
#include "tests/materials_fixture.hpp"
#include "voxel/voxel.hpp"

#include <catch2/catch.hpp>

#include <tbb/global_control.h>

#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <deque>
#include <limits>
#include <malloc.h>
#include <numeric>
#include <random>
#include <vector>

using namespace rodfab::materials;
using rodfab::test::kTestVoxel;
using rodfab::test::logPowerCalibration;

namespace {

// A modulus grid of random topology, on both sides of 0 and across a leaf parent's boundary (x = 128):
// leaves full, sparse and empty; moduli log-spread over 0.3 .. 400 MPa with the edge values mixed in
// (`edges`: each float exactly at, and one ulp either side of, the floor and the maximum; 0, -0, -5,
// infinities, denormals, huge), no NaN.
openvdb::FloatGrid::Ptr randomModulusGrid(std::uint64_t seed, const std::vector<float>& edges) {
  auto grid = openvdb::FloatGrid::create(0.0f);
  grid->setName("modulus_mpa");
  grid->setTransform(openvdb::math::Transform::createLinearTransform(0.05));
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> lnE(std::log(0.3), std::log(400.0)), unit(0.0, 1.0);
  auto acc = grid->getAccessor();
  for (int lx = -24; lx < 152; lx += 8)
    for (int ly = -8; ly < 24; ly += 8)
      for (int lz = -8; lz < 32; lz += 8) {
        const double density = std::array{0.0, 0.05, 0.5, 1.0}[random() % 4];  // per leaf
        for (int x = lx; x < lx + 8; ++x)
          for (int y = ly; y < ly + 8; ++y)
            for (int z = lz; z < lz + 8; ++z) {
              if (!(unit(random) < density)) continue;
              const float e = random() % 6 == 0 ? edges[random() % edges.size()] : static_cast<float>(std::exp(lnE(random)));
              acc.setValueOn(openvdb::Coord(x, y, z), e);
            }
      }
  return grid;
}

std::vector<float> edgeModuli(const FractionMap& map) {
  const float floor = static_cast<float>(map.floorMpa()), maximum = static_cast<float>(map.maxModulusMpa());
  const float inf = std::numeric_limits<float>::infinity();
  return {floor, std::nextafter(floor, 0.0f), std::nextafter(floor, inf), maximum, std::nextafter(maximum, 0.0f),
          std::nextafter(maximum, inf), 0.0f, -0.0f, -5.0f, inf, -inf, 1e30f, std::numeric_limits<float>::denorm_min(),
          std::numeric_limits<float>::max()};
}

// Two material grids hold the same voxels with the same bits: leaf by leaf, masks and values.
std::size_t differingLeaves(const openvdb::BoolGrid& a, const openvdb::BoolGrid& b) {
  std::size_t differing = a.tree().leafCount() != b.tree().leafCount() ? 1 : 0;
  for (auto leaf = a.tree().cbeginLeaf(); leaf; ++leaf) {
    const auto* other = b.tree().probeConstLeaf(leaf->origin());
    differing += !other || other->getValueMask() != leaf->getValueMask() || !(other->buffer() == leaf->buffer());
  }
  return differing;
}

// map-then-dither as the slicer did it before the two were fused: the band's fraction grid (and layer k1
// for a ditherer that reads it, not counted), then ditherLayers.
openvdb::BoolGrid::Ptr mapThenDither(Ditherer& ditherer, const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                     MappingStats& stats) {
  const auto fraction = mapToFractions(modulus, map, k0, k1, stats);
  if (ditherer.readsNextLayer()) {
    MappingStats ignored;
    fraction->tree().merge(mapToFractions(modulus, map, k1, k1 + 1, ignored)->tree());
  }
  return ditherer.ditherLayers(*fraction, k0, k1);
}

}  // namespace

TEST_CASE("materials: mapping and dithering in one pass gives map-then-dither's bits and counts, any band, seed and thread count",
          "[materials][mapping][fused]") {
  // Two calibrations: the bundled one (8 MPa floor = 30 % Vero) and one whose floor is the Tango modulus,
  // so the floor's fraction is 0; moduli at and beyond the maximum give 1.
  const std::vector<rodfab::calibration::Calibration> calibrations{rodfab::calibration::loadDefaultCalibration(),
                                                                    logPowerCalibration(0.5)};
  REQUIRE(calibrations[1].floorFraction() == 0.0);
  for (std::size_t c = 0; c < calibrations.size(); ++c) {
    const FractionMap map(calibrations[c]);
    for (const std::uint64_t seed : {1ull, 7ull, 0x9e3779b97f4a7c15ull}) {
      const auto modulus = randomModulusGrid(seed + c, edgeModuli(map));
      for (const std::string& method : ditherMethodNames()) {
        for (const auto& [threads, bandLayers] : {std::pair{1, 40}, std::pair{2, 8}, std::pair{2, 3}}) {
          INFO("calibration " << c << ", seed " << seed << ", " << method << ", " << threads << " thread(s), bands of " << bandLayers);
          tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
          const auto fused = makeDitherer(method, {seed}), reference = makeDitherer(method, {seed});
          CHECK(fused->mapsWhileDithering() == (method != "error-diffusion"));
          MappingStats fusedStats, referenceStats;
          std::size_t differing = 0, voxels = 0, vero = 0;
          for (int k0 = -8; k0 < 32; k0 += bandLayers) {  // consecutive bands from below the part, as error diffusion needs
            const auto material = fused->mapAndDitherLayers(*modulus, map, k0, k0 + bandLayers, fusedStats);
            const auto truth = mapThenDither(*reference, *modulus, map, k0, k0 + bandLayers, referenceStats);
            CHECK(material->getName() == kMaterialGridName);
            CHECK(material->transform() == modulus->transform());
            differing += differingLeaves(*material, *truth);
            voxels += material->activeVoxelCount();
            for (auto v = material->cbeginValueOn(); v; ++v) vero += *v;
          }
          CHECK(differing == 0);
          CHECK(voxels == modulus->activeVoxelCount());
          CHECK(vero > 0);  // both materials occur
          CHECK(vero < voxels);
          CHECK(fusedStats.voxels == referenceStats.voxels);
          CHECK(fusedStats.voxels == modulus->activeVoxelCount());
          CHECK(fusedStats.clamps.belowFloor == referenceStats.clamps.belowFloor);
          CHECK(fusedStats.clamps.aboveMax == referenceStats.clamps.aboveMax);
          CHECK(fusedStats.clamps.belowFloor > 0);
          CHECK(fusedStats.clamps.aboveMax > 0);
        }
      }
    }
  }
}

TEST_CASE("materials: mapping and dithering in one pass: active tiles, reversed bands, every fraction 0 or 1 where the map says so",
          "[materials][mapping][fused]") {
  const FractionMap map(logPowerCalibration(0.5));  // floor fraction 0
  auto modulus = randomModulusGrid(3, edgeModuli(map));
  // An active tile of a whole leaf at Tango's modulus (fraction 0) and one at the maximum (fraction 1).
  modulus->tree().addTile(1, openvdb::Coord(400, 0, 0), 0.5f, true);
  modulus->tree().addTile(1, openvdb::Coord(408, 0, 0), 190.0f, true);
  for (const char* method : {"white", "blue"}) {
    INFO(method);
    MappingStats fusedStats, referenceStats;
    const auto material = makeDitherer(method, {5})->mapAndDitherLayers(*modulus, map, -8, 32, fusedStats);
    const auto truth = mapThenDither(*makeDitherer(method, {5}), *modulus, map, -8, 32, referenceStats);
    CHECK(differingLeaves(*material, *truth) == 0);
    CHECK(fusedStats.voxels == modulus->activeVoxelCount());
    CHECK(fusedStats.voxels == referenceStats.voxels);
    CHECK(fusedStats.clamps.total() == referenceStats.clamps.total());
    const auto tango = material->tree().probeConstLeaf(openvdb::Coord(400, 0, 0));
    const auto vero = material->tree().probeConstLeaf(openvdb::Coord(408, 0, 0));
    REQUIRE(tango);
    REQUIRE(vero);
    CHECK(tango->getValueMask().isOn());
    CHECK(tango->buffer() == openvdb::BoolTree::LeafNodeType::Buffer(false));  // fraction 0: Tango everywhere
    CHECK(vero->buffer() == openvdb::BoolTree::LeafNodeType::Buffer(true));    // fraction 1: Vero everywhere
    MappingStats untouched;
    CHECK_THROWS_AS(makeDitherer(method, {5})->mapAndDitherLayers(*modulus, map, 4, 2, untouched), std::invalid_argument);
    CHECK(untouched.voxels == 0);
  }
}

TEST_CASE("materials: mapping and dithering in one pass checks for an interrupt before each leaf, one that throws leaves the counts untouched",
          "[materials][mapping][fused]") {
  const FractionMap map(rodfab::calibration::loadDefaultCalibration());
  const auto modulus = randomModulusGrid(11, edgeModuli(map));
  tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
  for (const char* method : {"white", "blue"}) {
    INFO(method);
    std::atomic<int> calls{0}, stopAt{0};
    struct Stop {};
    DitherOptions options(9);
    options.checkInterrupt = [&] {
      if (++calls == stopAt.load()) throw Stop{};
    };
    const auto ditherer = makeDitherer(method, options);
    MappingStats counted;
    const auto whole = ditherer->mapAndDitherLayers(*modulus, map, -8, 32, counted);
    CHECK(calls.load() == static_cast<int>(modulus->tree().leafCount()));
    const int leaves = calls.load();
    for (const int n : {1, 2, leaves}) {
      calls = 0;
      stopAt = n;
      MappingStats stopped;
      CHECK_THROWS_AS(ditherer->mapAndDitherLayers(*modulus, map, -8, 32, stopped), Stop);
      CHECK(stopped.voxels == 0);
      CHECK(stopped.clamps.total() == 0);
    }
    // Reset, it streams again: the same grid as before the interrupts.
    stopAt = 0;
    ditherer->reset();
    MappingStats again;
    CHECK(differingLeaves(*ditherer->mapAndDitherLayers(*modulus, map, -8, 32, again), *whole) == 0);
    CHECK(again.voxels == counted.voxels);
  }
}
