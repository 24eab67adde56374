// materials/: blue-noise masks and the ditherers against independent truth.
#include "materials/materials.hpp"
#include "tests/materials_fixture.hpp"

#include <catch2/catch.hpp>

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <random>

using namespace rodfab::materials;
using rodfab::test::kTestVoxel;

namespace {

// Same active voxels and the same value at each.
bool sameMaterial(const openvdb::BoolGrid& a, const openvdb::BoolGrid& b) {
  if (a.activeVoxelCount() != b.activeVoxelCount()) return false;
  auto other = b.getConstAccessor();
  for (auto it = a.cbeginValueOn(); it; ++it) {
    bool v = false;
    if (!other.probeValue(it.getCoord(), v) || v != *it) return false;
  }
  return true;
}

std::size_t countVero(const openvdb::BoolGrid& g) {
  std::size_t n = 0;
  for (auto it = g.cbeginValueOn(); it; ++it) n += *it ? 1 : 0;
  return n;
}

// A part with varying fractions, exact 0 and 1 regions, thin features and negative coordinates: a
// block whose fraction varies smoothly, a rod through it and a one-voxel-thick fin.
openvdb::FloatGrid::Ptr mixedPart() {
  auto grid = makeRod(0.8, 3.0, 2, 0.3f, kTestVoxel);
  auto acc = grid->getAccessor();
  for (int k = -5; k < 40; ++k)
    for (int j = -12; j < 20; ++j)
      for (int i = -20; i < 30; ++i) {
        float f = 0.5f + 0.45f * std::sin(0.15f * i) * std::cos(0.2f * j + 0.1f * k);
        if (i < -15) f = 0.0f;
        if (i > 25) f = 1.0f;
        acc.setValueOn(openvdb::Coord(i, j, k), f);
      }
  for (int k = 40; k < 70; ++k)
    for (int i = -20; i < 30; ++i) acc.setValueOn(openvdb::Coord(i, 3, k), 0.37f);
  return grid;
}

// The layers [k0, k1) of `grid`, as a streaming voxelizer would hand them over.
openvdb::FloatGrid::Ptr layersOf(const openvdb::FloatGrid& grid, int k0, int k1) {
  auto out = openvdb::FloatGrid::create(0.0f);
  out->setTransform(grid.transform().copy());
  auto acc = out->getAccessor();
  for (auto it = grid.cbeginValueOn(); it; ++it)
    if (it.getCoord().z() >= k0 && it.getCoord().z() < k1) acc.setValueOn(it.getCoord(), *it);
  return out;
}

std::filesystem::path tempPath(const std::string& name) {
  return std::filesystem::temp_directory_path() / ("rodfab-test-materials-" + name);
}

std::string readBytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void writeBytes(const std::filesystem::path& file, const std::string& bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

bool isPermutation(const std::vector<std::uint32_t>& ranks) {
  std::vector<std::uint32_t> sorted = ranks;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t r = 0; r < sorted.size(); ++r)
    if (sorted[r] != r) return false;
  return true;
}

}  // namespace

TEST_CASE("materials: the bundled blue-noise mask is a permutation and regenerates bit for bit", "[materials][mask]") {
  const auto bundled = BlueNoiseMask::bundled();
  const BlueNoiseParameters defaults = BlueNoiseParameters::bundledMask();
  REQUIRE(bundled->size() == defaults.size);
  REQUIRE(bundled->cellCount() == 64u * 32u * 90u);
  CHECK(isPermutation(bundled->ranks()));
  CHECK(bundled->parameters().seed == defaults.seed);
  CHECK(bundled->voxelSizeMm() == defaults.voxelSizeMm);  // the file records the voxel it was made for

  // A few seconds: the generator is fast enough to check the whole committed file in every run.
  const BlueNoiseMask regenerated = BlueNoiseMask::generate(defaults);
  CHECK(regenerated.ranks() == bundled->ranks());
  const auto copy = tempPath("mask.rfbn");
  regenerated.save(copy);
  CHECK(readBytes(copy) == readBytes(BlueNoiseMask::bundledPath()));
  std::filesystem::remove(copy);
}

TEST_CASE("materials: void-and-cluster masks: deterministic, seed-dependent, permutations, blue", "[materials][mask]") {
  BlueNoiseParameters p = BlueNoiseParameters::bundledMask();
  p.size = {24, 12, 34};
  const BlueNoiseMask a = BlueNoiseMask::generate(p);
  CHECK(isPermutation(a.ranks()));
  CHECK(BlueNoiseMask::generate(p).ranks() == a.ranks());
  p.seed = 2;
  CHECK(BlueNoiseMask::generate(p).ranks() != a.ranks());

  // Thresholds (rank + 0.5) / N: a fraction f turns on exactly round(f N) cells of a tile.
  const auto& t = a.thresholds();
  for (float f : {0.0f, 0.1f, 0.3f, 0.5f, 1.0f}) {
    const auto on = std::count_if(t.begin(), t.end(), [f](float x) { return f > x; });
    CHECK(on == std::lround(f * static_cast<double>(t.size())));
  }

  // Blue: the cells of the first 5 % of ranks (mean spacing about 0.13 mm) keep apart, so almost none
  // has another one as its x or z neighbour (0.042 / 0.030 mm away); for random cells 1 - 0.95^4 = 19 %
  // would. (y neighbours are 0.085 mm away: near the spacing, not a sign of clustering.)
  const std::size_t n = a.cellCount();
  const auto on = [&](int i, int j, int k) {
    const auto s = a.size();
    return a.rank((i + s[0]) % s[0], (j + s[1]) % s[1], (k + s[2]) % s[2]) < n / 20;
  };
  std::size_t members = 0, touching = 0;
  for (int k = 0; k < a.size()[2]; ++k)
    for (int j = 0; j < a.size()[1]; ++j)
      for (int i = 0; i < a.size()[0]; ++i) {
        if (!on(i, j, k)) continue;
        ++members;
        if (on(i - 1, j, k) || on(i + 1, j, k) || on(i, j, k - 1) || on(i, j, k + 1)) ++touching;
      }
  CHECK(members == n / 20);
  CHECK(static_cast<double>(touching) / members < 0.02);
}

TEST_CASE("materials: mask files: round trip and errors naming the file and field", "[materials][mask]") {
  BlueNoiseParameters p = BlueNoiseParameters::bundledMask();
  p.size = {8, 4, 10};
  const BlueNoiseMask mask = BlueNoiseMask::generate(p);
  const auto file = tempPath("small.rfbn");
  mask.save(file);
  const BlueNoiseMask loaded = BlueNoiseMask::load(file);
  CHECK(loaded.ranks() == mask.ranks());
  CHECK(loaded.parameters().sigmaMm == Approx(p.sigmaMm));
  CHECK(loaded.parameters().voxelSizeMm[1] == Approx(p.voxelSizeMm[1]));

  const std::string good = readBytes(file);
  const auto bad = tempPath("bad.rfbn");
  const auto expectError = [&](const std::string& bytes, const std::string& field) {
    writeBytes(bad, bytes);
    try {
      BlueNoiseMask::load(bad);
      FAIL("a broken mask file loaded");
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      CHECK_THAT(what, Catch::Contains(bad.string()) && Catch::Contains(field));
    }
  };
  expectError("not a mask", "magic");
  expectError(good.substr(0, good.size() - 3), "ranks");
  std::string duplicate = good;
  duplicate[good.size() - 40] = static_cast<char>(duplicate[good.size() - 40] ^ 0x10);  // one rank changed
  expectError(duplicate, "ranks");
  std::string version = good;
  version[8] = 9;
  expectError(version, "version");
  CHECK_THROWS_WITH(BlueNoiseMask::load(tempPath("missing.rfbn")), Catch::Contains("cannot open"));
  std::filesystem::remove(file);
  std::filesystem::remove(bad);

  p.size = {1, 4, 10};
  CHECK_THROWS_AS(BlueNoiseMask::generate(p), std::invalid_argument);
  // No printer's voxel is assumed: parameters without one are refused.
  BlueNoiseParameters noVoxel;
  noVoxel.size = {8, 4, 10};
  CHECK_THROWS_WITH(BlueNoiseMask::generate(noVoxel), Catch::Contains("voxel size on axis 0 must be > 0 mm"));
}

TEST_CASE("materials: ditherers: exact fractions 0 and 1, topology, grid names", "[materials][dither]") {
  for (const std::string& method : ditherMethodNames()) {
    INFO(method);
    const auto ditherer = makeDitherer(method, {7, nullptr});
    CHECK(ditherer->name() == method);
    const auto zero = makeUniformBlock(openvdb::Coord(20, 10, 12), 0.0f, kTestVoxel);
    const auto one = makeUniformBlock(openvdb::Coord(20, 10, 12), 1.0f, kTestVoxel);
    const auto tango = ditherer->dither(*zero);
    const auto vero = ditherer->dither(*one);
    CHECK(tango->activeVoxelCount() == 2400);
    CHECK(countVero(*tango) == 0);
    CHECK(countVero(*vero) == 2400);
    CHECK(vero->getName() == kMaterialGridName);
    CHECK(vero->transform() == one->transform());

    // In a mixed part, voxels at exactly 0 or 1 stay pure whatever their neighbours do.
    const auto part = mixedPart();
    const auto material = ditherer->dither(*part);
    REQUIRE(material->activeVoxelCount() == part->activeVoxelCount());
    CHECK(material->tree().hasSameTopology(openvdb::BoolTree(part->tree(), false, openvdb::TopologyCopy())));
    auto m = material->getConstAccessor();
    std::size_t wrong = 0;
    for (auto it = part->cbeginValueOn(); it; ++it)
      if ((*it == 0.0f && m.getValue(it.getCoord())) || (*it == 1.0f && !m.getValue(it.getCoord()))) ++wrong;
    CHECK(wrong == 0);
  }
}

TEST_CASE("materials: ditherers: identical for 1 and 2 threads and for any band size", "[materials][dither]") {
  const auto part = mixedPart();
  const openvdb::CoordBBox box = part->evalActiveVoxelBoundingBox();
  for (const std::string& method : ditherMethodNames()) {
    INFO(method);
    openvdb::BoolGrid::Ptr single, dual;
    {
      tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
      single = makeDitherer(method, {3, nullptr})->dither(*part);
    }
    {
      tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
      dual = makeDitherer(method, {3, nullptr})->dither(*part);
    }
    CHECK(sameMaterial(*single, *dual));
    // More workers than cores: error diffusion's layer wavefront then waits on preempted workers.
    tbb::task_arena four(4);
    CHECK(sameMaterial(*single, *four.execute([&] { return makeDitherer(method, {3, nullptr})->dither(*part); })));

    for (int band : {1, 5, 8, 13, 64}) {
      INFO("band of " << band << " layers");
      const auto ditherer = makeDitherer(method, {3, nullptr});
      auto merged = openvdb::BoolGrid::create(false);
      // Start below the part, as a slicer streaming the whole build volume would.
      for (int k0 = box.min().z() - 3; k0 <= box.max().z(); k0 += band) {
        const auto piece = ditherer->ditherLayers(*part, k0, k0 + band);
        for (auto it = piece->cbeginValueOn(); it; ++it) {
          CHECK((it.getCoord().z() >= k0 && it.getCoord().z() < k0 + band));
          merged->tree().setValueOn(it.getCoord(), *it);
        }
      }
      CHECK(sameMaterial(*merged, *single));
    }

    // Streaming from per-band grids that hold the band plus one layer (what error diffusion reads).
    const auto ditherer = makeDitherer(method, {3, nullptr});
    auto merged = openvdb::BoolGrid::create(false);
    for (int k0 = box.min().z(); k0 <= box.max().z(); k0 += 9) {
      const auto bandGrid = layersOf(*part, k0, k0 + 10);
      const auto piece = ditherer->ditherLayers(*bandGrid, k0, k0 + 9);
      for (auto it = piece->cbeginValueOn(); it; ++it) merged->tree().setValueOn(it.getCoord(), *it);
    }
    CHECK(sameMaterial(*merged, *single));
  }
}

TEST_CASE("materials: a band of a grid whose other leaves lie outside it holds the band's voxels only", "[materials][dither]") {
  // 33 layers: leaf rows at z = 0, 8, 16, 24 lie in layers [0, 32) and the row at z = 32 (layer 32
  // only) outside, so the band holds 4/5 of the leaves (the pointwise ditherers then copy the grid's
  // topology and prune what the band does not hold).
  const auto block = makeUniformBlock(openvdb::Coord(40, 24, 33), 0.45f, kTestVoxel);
  for (const std::string& method : {std::string("white"), std::string("blue")}) {
    INFO(method);
    const auto whole = makeDitherer(method, {4, nullptr})->dither(*block);
    const auto band = makeDitherer(method, {4, nullptr})->ditherLayers(*block, 0, 32);
    CHECK(band->activeVoxelCount() == 40 * 24 * 32);
    CHECK(band->tree().probeConstLeaf(openvdb::Coord(0, 0, 32)) == nullptr);
    std::size_t wrong = 0;
    const auto w = whole->getConstAccessor();
    for (auto it = band->cbeginValueOn(); it; ++it)
      wrong += it.getCoord().z() >= 32 || *it != w.getValue(it.getCoord());
    CHECK(wrong == 0);
  }
}

TEST_CASE("materials: error diffusion: a worker that throws stops the band, the others never hang", "[materials][dither]") {
  const auto part = mixedPart();
  const auto reference = makeDitherer("error-diffusion", {3, nullptr})->dither(*part);
  const int layers = part->evalActiveVoxelBoundingBox().dim().z();
  // checkInterrupt runs before each layer, on whichever worker claims it: throw at the n-th call.
  for (int workers : {2, 4}) {
    tbb::task_arena arena(workers);
    for (int stopAt = 1; stopAt <= layers + 1; ++stopAt) {
      INFO(workers << " workers, stop at call " << stopAt);
      std::atomic<int> calls{0};
      DitherOptions options{3, nullptr};
      options.checkInterrupt = [&] {
        if (++calls == stopAt) throw std::runtime_error("stop requested");
      };
      const auto ditherer = makeDitherer("error-diffusion", options);
      if (stopAt <= layers) {
        CHECK_THROWS_WITH(arena.execute([&] { return ditherer->dither(*part); }), "stop requested");
        ditherer->reset();  // a ditherer left by an exception streams again after reset()
      }
      CHECK(sameMaterial(*arena.execute([&] { return ditherer->dither(*part); }), *reference));
    }
  }
}

TEST_CASE("materials: white and blue noise check for an interrupt before every leaf and stop at it", "[materials][dither]") {
  const auto part = mixedPart();
  const std::size_t leaves = part->tree().leafCount();
  for (const std::string method : {"white", "blue"}) {
    const auto reference = makeDitherer(method, {3, nullptr})->dither(*part);
    std::atomic<std::size_t> calls{0};
    DitherOptions counting{3, nullptr};
    counting.checkInterrupt = [&] { ++calls; };
    CHECK(sameMaterial(*makeDitherer(method, counting)->dither(*part), *reference));
    CHECK(calls == leaves);  // one call a leaf of the fraction grid
    for (const std::size_t stopAt : {std::size_t{1}, leaves / 2, leaves}) {
      INFO(method << ", stop at call " << stopAt << " of " << leaves);
      std::atomic<std::size_t> n{0};
      DitherOptions options{3, nullptr};
      options.checkInterrupt = [&] {
        if (++n == stopAt) throw std::runtime_error("stop requested");
      };
      const auto ditherer = makeDitherer(method, options);
      CHECK_THROWS_WITH(ditherer->dither(*part), "stop requested");
      ditherer->reset();
      n = leaves + 1;  // no further throw: the ditherer still gives the reference pattern
      CHECK(sameMaterial(*ditherer->dither(*part), *reference));
    }
  }
}

TEST_CASE("materials: ditherers: a seed fixes the pattern, another seed changes it", "[materials][dither]") {
  const auto block = makeUniformBlock(openvdb::Coord(40, 20, 30), 0.3f, kTestVoxel);
  for (const std::string& method : ditherMethodNames()) {
    INFO(method);
    const auto a = makeDitherer(method, {11, nullptr})->dither(*block);
    const auto b = makeDitherer(method, {11, nullptr})->dither(*block);
    const auto c = makeDitherer(method, {12, nullptr})->dither(*block);
    CHECK(sameMaterial(*a, *b));
    CHECK_FALSE(sameMaterial(*a, *c));
  }
}

TEST_CASE("materials: ditherers: active tiles are dithered like the same voxels in leaves", "[materials][dither]") {
  auto tiled = openvdb::FloatGrid::create(0.0f);
  tiled->tree().fill(openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(31, 15, 23)), 0.4f, true);
  REQUIRE(tiled->tree().hasActiveTiles());
  const auto voxels = tiled->deepCopy();
  voxels->tree().voxelizeActiveTiles();
  for (const std::string& method : ditherMethodNames()) {
    INFO(method);
    const auto a = makeDitherer(method, {5, nullptr})->dither(*tiled);
    CHECK(a->activeVoxelCount() == 32 * 16 * 24);
    CHECK(sameMaterial(*a, *makeDitherer(method, {5, nullptr})->dither(*voxels)));
  }
}

TEST_CASE("materials: ditherers: bad input is named", "[materials][dither]") {
  CHECK_THROWS_WITH(makeDitherer("floyd"), Catch::Contains("unknown ditherer 'floyd'") && Catch::Contains("error-diffusion"));
  auto grid = makeUniformBlock(openvdb::Coord(10, 10, 10), 0.5f, kTestVoxel);
  grid->tree().setValue(openvdb::Coord(3, 4, 5), 1.5f);
  for (const std::string& method : ditherMethodNames()) {
    INFO(method);
    const auto ditherer = makeDitherer(method);
    CHECK_THROWS_WITH(ditherer->dither(*grid), Catch::Contains("(3, 4, 5)") && Catch::Contains("1.5") &&
                                                   Catch::Contains("expected a Vero fraction in [0, 1]"));
    CHECK_THROWS_AS(ditherer->ditherLayers(*grid, 5, 2), std::invalid_argument);
  }
  grid->tree().setValue(openvdb::Coord(3, 4, 5), std::numeric_limits<float>::quiet_NaN());
  CHECK_THROWS_WITH(makeDitherer("white")->dither(*grid), Catch::Contains("(3, 4, 5)"));
  // Error diffusion's workers each find bad voxels; the first in leaf order is reported, as above.
  grid->tree().setValue(openvdb::Coord(6, 2, 7), -0.5f);
  tbb::task_arena four(4);
  four.execute([&] { CHECK_THROWS_WITH(makeDitherer("error-diffusion")->dither(*grid), Catch::Contains("(3, 4, 5)")); });

  // Error diffusion streams: bands must follow each other, and consecutive grids must agree.
  const auto block = makeUniformBlock(openvdb::Coord(10, 10, 10), 0.3f, kTestVoxel);
  const auto ed = makeDitherer("error-diffusion");
  ed->ditherLayers(*block, 0, 4);
  CHECK_THROWS_WITH(ed->ditherLayers(*block, 5, 8), Catch::Contains("expected a band starting at layer 4"));
  ed->reset();
  ed->ditherLayers(*block, 0, 4);
  auto shrunk = layersOf(*block, 4, 10);
  shrunk->tree().setValueOff(openvdb::Coord(2, 2, 4));
  CHECK_THROWS_WITH(ed->ditherLayers(*shrunk, 4, 8), Catch::Contains("(2, 2, 4)") && Catch::Contains("disagree"));
}
