// materials/: the modulus-to-fraction table and the mapping of modulus grids to fraction grids.
#include "geometry/geometry.hpp"
#include "materials/materials.hpp"
#include "tests/materials_fixture.hpp"
#include "voxel/voxel.hpp"

#include "tests/heap_in_use.hpp"

#include <catch2/catch.hpp>

#include <tbb/global_control.h>

#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <deque>
#include <limits>
#include <numeric>
#include <random>
#include <vector>

using namespace rodfab::materials;
using rodfab::test::kTestVoxel;
using rodfab::test::logPowerCalibration;

namespace {


double logPowerFraction(double modulusMpa) { return std::sqrt(std::log(modulusMpa / 0.5) / std::log(190.0 / 0.5)); }

// Moduli from 2 to 400 MPa, log-spaced along x, plus a NaN voxel: every clamp kind occurs.
openvdb::FloatGrid::Ptr modulusBlock() {
  auto grid = makeUniformBlock(openvdb::Coord(60, 9, 21), 0.0f, kTestVoxel);
  grid->setName("modulus_mpa");
  for (auto it = grid->beginValueOn(); it; ++it) {
    const openvdb::Coord c = it.getCoord();
    it.setValue(static_cast<float>(2.0 * std::pow(200.0, (c.x() + 0.1 * c.y() + 0.01 * c.z()) / 60.0)));
  }
  grid->tree().setValue(openvdb::Coord(5, 5, 5), std::numeric_limits<float>::quiet_NaN());
  return grid;
}

}  // namespace

TEST_CASE("materials: the ln E lookup table meets its error bound against the exact inverse", "[materials][mapping]") {
  const auto calibration = logPowerCalibration();
  const FractionMap map(calibration);
  CHECK(map.floorFraction() == Approx(logPowerFraction(8.0)));
  CHECK(map.interpolationErrorBound() < 1e-6);

  std::mt19937_64 random(42);
  std::uniform_real_distribution<double> lnE(std::log(8.0), std::log(190.0));
  double worst = 0.0, previous = -1.0;
  std::vector<double> moduli(100000);
  for (double& e : moduli) e = std::exp(lnE(random));
  std::sort(moduli.begin(), moduli.end());
  for (double e : moduli) {
    const auto r = map.fraction(e);
    REQUIRE(r.clamp == rodfab::calibration::Clamp::None);
    worst = std::max(worst, std::abs(r.fraction - logPowerFraction(e)));
    CHECK(r.fraction >= previous);  // monotone
    previous = r.fraction;
  }
  CHECK(worst <= map.interpolationErrorBound());

  // A coarse table has a larger, still honest bound.
  const FractionMap coarse(calibration, 16);
  double coarseWorst = 0.0;
  for (double e : moduli) coarseWorst = std::max(coarseWorst, std::abs(coarse.fraction(e).fraction - logPowerFraction(e)));
  CHECK(coarseWorst <= coarse.interpolationErrorBound());
  CHECK(coarseWorst > map.interpolationErrorBound());

  // The bundled default calibration, against its own exact inverse.
  const auto bundled = rodfab::calibration::loadDefaultCalibration();
  const FractionMap bundledMap(bundled);
  double bundledWorst = 0.0;
  for (double e = bundled.floorMpa(); e <= bundled.maxModulusMpa(); e *= 1.0007)
    bundledWorst = std::max(bundledWorst, std::abs(bundledMap.fraction(e).fraction - bundled.fraction(e).fraction));
  CHECK(bundledWorst <= bundledMap.interpolationErrorBound());
  CHECK(bundledMap.interpolationErrorBound() < 1e-5);

  CHECK_THROWS_AS(FractionMap(calibration, 1), std::invalid_argument);
}

TEST_CASE("materials: the table clamps exactly like the calibration", "[materials][mapping]") {
  using rodfab::calibration::Clamp;
  const auto calibration = logPowerCalibration();
  const FractionMap map(calibration);
  for (double e : {1.0, 7.999, 8.0, 8.001, 50.0, 189.99, 190.0, 190.01, 1e6, -3.0}) {
    INFO(e);
    const auto table = map.fraction(e);
    const auto exact = calibration.fraction(e);
    CHECK(table.clamp == exact.clamp);
    CHECK(table.fraction == Approx(exact.fraction).margin(map.interpolationErrorBound()));
  }
  CHECK(map.fraction(std::numeric_limits<double>::quiet_NaN()).clamp == Clamp::BelowFloor);
  CHECK(map.fraction(8.0).fraction == calibration.floorFraction());
  CHECK(map.fraction(190.0).fraction == 1.0);
}

TEST_CASE("materials: E exactly at a floor or maximum that floats cannot hold is not a clamp", "[materials][mapping]") {
  rodfab::calibration::ModelParameters p;
  p.model = rodfab::calibration::Model::LogPower;
  p.tangoModulusMpa = 0.5;
  p.veroModulusMpa = 190.3;
  p.exponent = 2.0;
  const rodfab::calibration::Calibration calibration(p, 8.3);
  const FractionMap map(calibration);
  REQUIRE(double(static_cast<float>(8.3)) != 8.3);  // the grid's float lies beside the floor
  auto grid = makeUniformBlock(openvdb::Coord(4, 1, 1), 0.0f, kTestVoxel);
  const float floor = static_cast<float>(8.3), maximum = static_cast<float>(calibration.maxModulusMpa());
  const float values[4] = {floor, maximum, std::nextafter(floor, 0.0f), std::nextafter(maximum, 1e9f)};
  for (int x = 0; x < 4; ++x) grid->tree().setValue(openvdb::Coord(x, 0, 0), values[x]);
  MappingStats stats;
  const auto fractions = mapToFractions(*grid, map, stats);
  CHECK(stats.clamps.belowFloor == 1);  // only the float below the floor's own
  CHECK(stats.clamps.aboveMax == 1);
  CHECK(fractions->tree().getValue(openvdb::Coord(0, 0, 0)) == Approx(map.floorFraction()).margin(1e-6));
  CHECK(fractions->tree().getValue(openvdb::Coord(1, 0, 0)) == Approx(1.0).margin(1e-6));
}

TEST_CASE("materials: modulus grids map to fraction grids with counted clamps, by bands and threads", "[materials][mapping]") {
  const auto calibration = logPowerCalibration();
  const FractionMap map(calibration);
  const auto modulus = modulusBlock();

  MappingStats stats;
  openvdb::FloatGrid::Ptr whole;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    whole = mapToFractions(*modulus, map, stats);
  }
  CHECK(whole->getName() == kFractionGridName);
  CHECK(whole->transform() == modulus->transform());
  CHECK(whole->tree().hasSameTopology(modulus->tree()));

  // Clamps counted independently, voxel by voxel.
  std::uint64_t below = 0, above = 0;
  auto fractions = whole->getConstAccessor();
  for (auto it = modulus->cbeginValueOn(); it; ++it) {
    const double e = *it;
    if (!(e >= 8.0)) {
      ++below;
      CHECK(fractions.getValue(it.getCoord()) == static_cast<float>(map.floorFraction()));
    } else if (e > 190.0) {
      ++above;
      CHECK(fractions.getValue(it.getCoord()) == 1.0f);
    } else {
      CHECK(fractions.getValue(it.getCoord()) == Approx(logPowerFraction(e)).margin(1e-6));
    }
  }
  CHECK(stats.voxels == modulus->activeVoxelCount());
  CHECK(stats.clamps.belowFloor == below);
  CHECK(stats.clamps.aboveMax == above);
  CHECK(below > 1);
  CHECK(above > 0);

  // Two threads, bands of 4 layers: the same grid and the same counts.
  tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
  MappingStats banded;
  auto merged = openvdb::FloatGrid::create(0.0f);
  for (int k0 = -2; k0 < 21; k0 += 4) {
    const auto piece = mapToFractions(*modulus, map, k0, k0 + 4, banded);
    for (auto it = piece->cbeginValueOn(); it; ++it) merged->tree().setValueOn(it.getCoord(), *it);
  }
  CHECK(banded.voxels == stats.voxels);
  CHECK(banded.clamps.belowFloor == below);
  CHECK(banded.clamps.aboveMax == above);
  CHECK(merged->tree().hasSameTopology(whole->tree()));
  std::size_t differing = 0;
  for (auto it = whole->cbeginValueOn(); it; ++it)
    differing += merged->tree().getValue(it.getCoord()) != *it;
  CHECK(differing == 0);

  CHECK_THROWS_AS(mapToFractions(*modulus, map, 4, 2, banded), std::invalid_argument);

  // An interrupt check runs before each leaf: it is called once per leaf of the band when it never
  // throws, and what it throws at the n-th call leaves mapToFractions with the counts untouched.
  const openvdb::CoordBBox box = modulus->evalActiveVoxelBoundingBox();
  const int k0 = box.min().z(), k1 = box.max().z() + 1;
  std::atomic<int> calls{0};
  MappingStats counted;
  mapToFractions(*modulus, map, k0, k1, counted, [&] { ++calls; });
  CHECK(calls.load() == static_cast<int>(modulus->tree().leafCount()));
  struct Stop {};
  for (const int n : {1, 2, calls.load()}) {
    std::atomic<int> seen{0};
    MappingStats stopped;
    CHECK_THROWS_AS(mapToFractions(*modulus, map, k0, k1, stopped, [&] { if (++seen == n) throw Stop{}; }), Stop);
    CHECK(stopped.voxels == 0);
    CHECK(stopped.clamps.total() == 0);
  }

  // The mapped fractions dither like any other: the whole chain, modulus to material.
  const auto material = makeDitherer("blue")->dither(*whole);
  CHECK(material->activeVoxelCount() == modulus->activeVoxelCount());
}

TEST_CASE("materials: a leaf word maps four voxels a step exactly as the scalar rule, clamps and inactive voxels included", "[materials][mapping]") {
  // The rule mapToFractions states, voxel by voxel: the clamps decided on the float, else the table.
  const auto calibration = logPowerCalibration();
  const FractionMap map(calibration);
  const float floor = static_cast<float>(map.floorMpa()), maximum = static_cast<float>(map.maxModulusMpa());
  const auto scalar = [&](float e) {
    if (!(e >= floor)) return static_cast<float>(map.floorFraction());
    if (e > maximum) return 1.0f;
    return static_cast<float>(map.interpolate(e));
  };
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> special = {floor, std::nextafter(floor, 0.0f), std::nextafter(floor, inf), maximum,
                                      std::nextafter(maximum, 0.0f), std::nextafter(maximum, inf), 0.0f, -0.0f, -5.0f, nan,
                                      -nan, inf, -inf, 1e30f, 1e-30f, std::numeric_limits<float>::denorm_min(), 50.0f, 189.9f};
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> lnE(std::log(1.0), std::log(400.0));
  // Rounds 200 on: words whose active voxels share one modulus bit for bit (each special value and
  // random ones; mapWord maps such a word once), with other values in the inactive voxels, and in every
  // third one the last active voxel a float apart, in every third another one (no longer uniform).
  for (int round = 0; round < 400; ++round) {
    std::array<float, 64> moduli{};
    for (std::size_t b = 0; b < 64; ++b)
      moduli[b] = (round + b) % 5 == 0 ? special[(round * 7 + b) % special.size()] : static_cast<float>(std::exp(lnE(random)));
    // Every kind of activity: none, all, single bits, whole quads off, random.
    const std::uint64_t active = round % 200 == 0 ? 0 : round % 200 == 1 ? ~std::uint64_t{0} : round % 200 == 2 ? 0x8000000000000001ull
                                 : round % 200 == 3 ? 0xf0f0f0f00f0f0f0full : round >= 200 && round % 4 < 2 ? ~std::uint64_t{0} >> (round % 7) : random();
    if (round >= 200) {
      const float shared = round % 2 ? special[std::size_t(round / 2) % special.size()] : static_cast<float>(std::exp(lnE(random)));
      for (std::size_t b = 0; b < 64; ++b)
        if (active >> b & 1) moduli[b] = shared;
      if (round % 3 == 0 && active) moduli[std::size_t(63 - std::countl_zero(active))] = std::nextafter(shared, 1e9f);
      // A voxel between the first and the last active a float apart (mapWord looks at the ends first).
      if (round % 3 == 1 && std::popcount(active) > 2) moduli[std::size_t(std::countr_zero(active & (active - 1)))] = std::nextafter(shared, 0.0f);
    }
    std::array<float, 64> fractions;
    fractions.fill(-1.0f);  // every value is written, the inactive ones as 0
    const FractionMap::WordClamps clamps = map.mapWord(moduli.data(), active, fractions.data());
    std::uint64_t below = 0, above = 0;
    for (std::size_t b = 0; b < 64; ++b) {
      INFO("round " << round << " voxel " << b << " E " << moduli[b]);
      if (!(active >> b & 1)) {
        CHECK(std::bit_cast<std::uint32_t>(fractions[b]) == 0u);  // +0, the background
        continue;
      }
      CHECK(std::bit_cast<std::uint32_t>(fractions[b]) == std::bit_cast<std::uint32_t>(scalar(moduli[b])));
      below += !(moduli[b] >= floor);
      above += moduli[b] > maximum;
    }
    CHECK(clamps.belowFloor == below);
    CHECK(clamps.aboveMax == above);
  }
}

TEST_CASE("materials: a leaf's words map in one call exactly as word by word, clamps summed", "[materials][mapping]") {
  const FractionMap map(logPowerCalibration());
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> lnE(std::log(1.0), std::log(400.0));
  for (int round = 0; round < 50; ++round) {
    std::array<float, 512> moduli;
    std::array<std::uint64_t, 8> active;
    for (std::size_t w = 0; w < 8; ++w) {
      // Words of every kind in one leaf: empty, full, random, one value throughout (the uniform path).
      const int kind = static_cast<int>((round + w) % 4);
      active[w] = kind == 0 ? 0 : kind == 1 ? ~std::uint64_t{0} : random();
      const float shared = static_cast<float>(std::exp(lnE(random)));
      for (std::size_t b = 0; b < 64; ++b) moduli[64 * w + b] = kind == 3 ? shared : static_cast<float>(std::exp(lnE(random)));
    }
    std::array<float, 512> together, apart;
    together.fill(-1.0f);
    apart.fill(-1.0f);
    const FractionMap::WordClamps sum = map.mapWords(moduli.data(), active.data(), active.size(), together.data());
    std::uint64_t below = 0, above = 0;
    for (std::size_t w = 0; w < 8; ++w) {
      const FractionMap::WordClamps c = map.mapWord(moduli.data() + 64 * w, active[w], apart.data() + 64 * w);
      below += c.belowFloor;
      above += c.aboveMax;
    }
    CAPTURE(round);
    CHECK(sum.belowFloor == below);
    CHECK(sum.aboveMax == above);
    CHECK(below + above > 0);  // the moduli range past both clamps: the sums are exercised
    for (std::size_t v = 0; v < 512; ++v) CHECK(std::bit_cast<std::uint32_t>(together[v]) == std::bit_cast<std::uint32_t>(apart[v]));
  }
}

TEST_CASE("materials: voxels far apart, negative coordinates included, map into the nodes OpenVDB puts them in", "[materials][mapping]") {
  // Leaves in different leaf parents (128 voxels) and upper nodes (4096), on both sides of 0: the output
  // tree is assembled parent by parent, then upper node by upper node.
  const FractionMap map(logPowerCalibration());
  auto modulus = openvdb::FloatGrid::create(0.0f);
  const std::vector<openvdb::Coord> where = {{0, 0, 0},       {1, 0, 0},      {200, 3, 1},       {5000, -300, 2},
                                             {-5000, 9000, 3}, {-1, -1, -1}, {-4097, -129, 0}};
  for (std::size_t v = 0; v < where.size(); ++v) modulus->tree().setValueOn(where[v], 3.0f + 40.0f * static_cast<float>(v));
  MappingStats stats;
  const auto fractions = mapToFractions(*modulus, map, -10, 10, stats);
  CHECK(stats.voxels == where.size());
  CHECK(stats.clamps.belowFloor == 1);  // 3 MPa
  CHECK(fractions->tree().hasSameTopology(modulus->tree()));
  CHECK(fractions->tree().nodeCount() == modulus->tree().nodeCount());
  for (const openvdb::Coord& c : where) {
    const float e = modulus->tree().getValue(c);
    CHECK(fractions->tree().getValue(c) == static_cast<float>(map.fraction(e).fraction));
  }
}

TEST_CASE("materials: streamed bands reuse earlier fraction grids' nodes and stay exact, whatever the owners did to them", "[materials][mapping]") {
  const FractionMap map(logPowerCalibration());
  // The clamp block with whole words and single voxels switched off, so reused leaves meet inactive
  // words and inactive voxels that their earlier band had active.
  const auto modulus = modulusBlock();
  for (auto it = modulus->beginValueOn(); it; ++it) {
    const openvdb::Coord c = it.getCoord();
    if ((c.x() % 8 == 3) || (c.x() * 7 + c.y() * 3 + c.z()) % 5 == 0) it.setValueOff();
  }
  tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
  for (int bandLayers : {4, 3}) {
    INFO("bands of " << bandLayers << " layers");
    rodfab::voxel::TreeRecycler<openvdb::FloatTree> recycler(0.0f);
    openvdb::FloatGrid::Ptr kept;  // one band alive while the next is made, as in the slicer
    MappingStats streamedStats, freshStats;
    std::size_t wrong = 0, dirty = 0;
    for (int k0 = -2; k0 < 21; k0 += bandLayers) {
      const auto band = mapToFractions(*modulus, map, k0, k0 + bandLayers, streamedStats, recycler);
      const auto fresh = mapToFractions(*modulus, map, k0, k0 + bandLayers, freshStats);
      CHECK(band->tree().hasSameTopology(fresh->tree()));
      CHECK(band->tree().nodeCount() == fresh->tree().nodeCount());
      CHECK(band->getName() == kFractionGridName);
      const auto truth = fresh->getConstAccessor();
      for (auto leaf = band->tree().cbeginLeaf(); leaf; ++leaf) {
        dirty += leaf->transientData() != 0;
        for (openvdb::Index n = 0; n < openvdb::FloatTree::LeafNodeType::SIZE; ++n) {
          const openvdb::Coord c = leaf->offsetToGlobalCoord(n);
          wrong += leaf->isValueOn(n) != truth.isValueOn(c) || std::bit_cast<std::uint32_t>(leaf->getValue(n)) !=
                                                                    std::bit_cast<std::uint32_t>(truth.getValue(c));
        }
      }
      if (kept) {  // the owner changes the previous band's grid, then lets it go
        for (auto leaf = kept->tree().beginLeaf(); leaf; ++leaf) {
          leaf->setValueOff(0, 7.0f);
          leaf->setValueOn(511, -3.0f);
          leaf->setTransientData(99);
        }
        kept->tree().addTile(1, openvdb::Coord(300, 0, 0), 0.5f, true);
        kept->tree().addTile(2, openvdb::Coord(9000, 0, 0), 0.25f, false);
      }
      kept = band;
    }
    CHECK(wrong == 0);
    CHECK(dirty == 0);
    CHECK(streamedStats.voxels == freshStats.voxels);
    CHECK(streamedStats.voxels == modulus->activeVoxelCount());
    CHECK(streamedStats.clamps.belowFloor == freshStats.clamps.belowFloor);
    CHECK(streamedStats.clamps.aboveMax == freshStats.clamps.aboveMax);
  }
}

using rodfab::tests::heapBytesInUse;

TEST_CASE("materials: the slice's memory estimate bounds the heap of streamed bands, recyclers included", "[materials][mapping][memory]") {
#if defined(__SANITIZE_ADDRESS__)
  WARN("AddressSanitizer keeps its own heap: mallinfo2 does not see it, nothing to measure");
  return;
#endif
  // The truth is glibc's count of the bytes in use, sampled as bands stream the way the slicer streams
  // them (slicer/job_pipeline.cpp: two bands in flight; a band's fractions are let go once dithered,
  // its moduli once written) with the rasterizer's and the mapping's TreeRecyclers in use, and then
  // with both recyclers full (kKeptTrees let-go trees each) while two bands are alive.
  using namespace rodfab;
  const geometry::NurbsCurve post(1, {0, 0, 1, 1}, {geometry::Vec3(0, 0, 0), geometry::Vec3(0, 0, 7)});
  const geometry::NurbsCurve strut(1, {0, 0, 1, 1}, {geometry::Vec3(-2, -1, 0.5), geometry::Vec3(3, 2, 6.5)});
  const geometry::RodStructure design{
      "memory", {geometry::Rod("post", post, geometry::Section::circle(4.0), std::nullopt, std::nullopt, geometry::CapStyle::Round,
                               geometry::BSplineField::constant(20, 0, 1)),
                 geometry::Rod("strut", strut, geometry::Section::circle(1.5), std::nullopt, std::nullopt, geometry::CapStyle::Flat,
                               geometry::BSplineField(1, {0, 0, 1, 1}, {2.0, 150.0}))}};
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, kTestVoxel);
  constexpr int kBandLayers = 16;
  constexpr std::size_t kBandsInFlight = 2;
  const voxel::RasterEstimate estimate = voxel::estimateRaster(design, grid, kBandLayers);
  const FractionMap map(logPowerCalibration());
  tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);

  const std::uint64_t before = heapBytesInUse();
  std::uint64_t streamedPeak = 0, fullRecyclers = 0, aliveGrids = 0;
  const auto heap = [&] { return heapBytesInUse() - std::min(before, heapBytesInUse()); };
  {
    const voxel::Rasterizer rasterizer(design, grid, {2});
    voxel::TreeRecycler<openvdb::FloatTree> fractionTrees(0.0f);
    MappingStats stats;
    struct Band {
      openvdb::FloatGrid::Ptr moduli, fractions;
    };
    const auto make = [&](int k0) {
      Band band{rasterizer.rasterizeLayers(k0, k0 + kBandLayers).grid, nullptr};
      streamedPeak = std::max(streamedPeak, heap());
      band.fractions = mapToFractions(*band.moduli, map, k0, k0 + kBandLayers, stats, fractionTrees);
      streamedPeak = std::max(streamedPeak, heap());
      return band;
    };
    std::deque<Band> alive;
    int k0 = 0;
    for (; k0 + 3 * kBandLayers < grid.dims.z(); k0 += kBandLayers) {
      if (alive.size() == kBandsInFlight) alive.pop_front();  // written: its moduli go back to the rasterizer
      alive.push_back(make(k0));
      alive.back().fractions.reset();  // dithered: the fractions go back to the mapping's recycler
    }
    // Two more bands made while two are alive and let go at once: both recyclers now hold kKeptTrees.
    Band extra[2] = {make(k0), make(k0 + kBandLayers)};
    for (Band& b : extra) b = Band{};
    fullRecyclers = heap();
    for (Band& b : alive) aliveGrids += b.moduli->memUsage();
  }
  const double bound = estimate.peakBytes(int(kBandsInFlight), 2 * voxel::TreeRecycler<openvdb::FloatTree>::kKeptTrees);  // both recyclers keep the default
  CAPTURE(before, streamedPeak, fullRecyclers, aliveGrids, estimate.pieceBytes, estimate.bandBytes, bound);
  REQUIRE(fullRecyclers > aliveGrids + 2 * voxel::TreeRecycler<openvdb::FloatTree>::kKeptTrees * 100'000);  // the kept trees are there
  REQUIRE(bound >= double(streamedPeak));
  REQUIRE(bound >= double(fullRecyclers));
}
