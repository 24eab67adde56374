// materials/: the "error-diffusion" ditherer against a plain single sweep written from its definition
// (error_diffusion.hpp), voxel for voxel, on irregular parts, for 1, 2 and 4 workers and in bands; its
// workingBytes against the heap it holds while dithering and keeps between bands.
#include "materials/counter_hash.hpp"
#include "materials/error_diffusion.hpp"
#include "materials/materials.hpp"

#include "tests/heap_in_use.hpp"

#include <catch2/catch.hpp>

#include <tbb/task_arena.h>


#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <random>
#include <vector>

using namespace rodfab::materials;

namespace {

const openvdb::Vec3d kVoxel(0.04, 0.08, 0.03);

// A part in `box` with holes and thin walls: each voxel is inside with probability 0.8, and whole
// columns and slabs are cut out, so rows break into runs and neighbours are missing in every
// direction. Fractions are uniform in [0, 1] with a share exactly 0 and exactly 1.
openvdb::FloatGrid::Ptr irregularPart(const openvdb::CoordBBox& box, std::uint32_t seed) {
  auto grid = openvdb::FloatGrid::create(0.0f);
  grid->setTransform(openvdb::math::Transform::createLinearTransform(openvdb::math::scale<openvdb::Mat4d>(kVoxel)));
  grid->setName(kFractionGridName);
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  auto acc = grid->getAccessor();
  for (auto it = box.begin(); it; ++it) {
    const openvdb::Coord c = *it;
    if (unit(random) > 0.8f || (c.x() % 7 == 3 && c.y() % 5 != 0) || c.z() % 11 == 5) continue;
    const float r = unit(random);
    acc.setValueOn(c, r < 0.05f ? 0.0f : r > 0.95f ? 1.0f : unit(random));
  }
  return grid;
}

// The definition, swept once over the box: layers by k, rows by j, a row towards +x when j + k is even;
// each voxel Vero when its fraction is 1, or above 0 and its fraction plus the error it received reaches
// 0.5 + jitter * (u - 0.5) (u: voxelUniform); what is left goes to (i + d, j), (i - d, j + 1),
// (i, j + 1), (i + d, j + 1) in the layer with Floyd-Steinberg's 7, 3, 5, 1 sixteenths of 1 - share,
// and to (i, j, k + 1) with the share, renormalized over those inside the part.
openvdb::BoolGrid::Ptr referenceSweep(const openvdb::FloatGrid& part, std::uint64_t seed) {
  const openvdb::CoordBBox box = part.evalActiveVoxelBoundingBox();
  const openvdb::Coord size = box.dim();
  const auto index = [&](int i, int j, int k) {
    return (static_cast<std::size_t>(k - box.min().z()) * size.y() + (j - box.min().y())) * size.x() + (i - box.min().x());
  };
  const auto inside = [&](int i, int j, int k) {
    return box.isInside(openvdb::Coord(i, j, k)) && part.tree().isValueOn(openvdb::Coord(i, j, k));
  };
  std::vector<float> error(static_cast<std::size_t>(size.x()) * size.y() * size.z(), 0.0f);
  const float share = ErrorDiffusionDitherer::kShareToNextLayer, inLayer = 1.0f - share;
  const std::array<float, 4> weight{7.0f / 16 * inLayer, 3.0f / 16 * inLayer, 5.0f / 16 * inLayer, 1.0f / 16 * inLayer};
  auto material = openvdb::BoolGrid::create(false);
  auto out = material->getAccessor();
  for (int k = box.min().z(); k <= box.max().z(); ++k)
    for (int j = box.min().y(); j <= box.max().y(); ++j) {
      const int d = ((j + k) & 1) ? -1 : 1;
      for (int step = 0; step < size.x(); ++step) {
        const int i = d > 0 ? box.min().x() + step : box.max().x() - step;
        if (!inside(i, j, k)) continue;
        const float f = part.tree().getValue(openvdb::Coord(i, j, k));
        const float wanted = f + error[index(i, j, k)];
        const float threshold = 0.5f + ErrorDiffusionDitherer::kThresholdJitter * (voxelUniform(seed, i, j, k) - 0.5f);
        const bool vero = f >= 1.0f || (f > 0.0f && wanted >= threshold);
        out.setValueOn(openvdb::Coord(i, j, k), vero);
        const float residual = wanted - (vero ? 1.0f : 0.0f);
        const std::array<openvdb::Coord, 4> target{openvdb::Coord(i + d, j, k), openvdb::Coord(i - d, j + 1, k),
                                                   openvdb::Coord(i, j + 1, k), openvdb::Coord(i + d, j + 1, k)};
        const bool up = inside(i, j, k + 1);
        float total = up ? share : 0.0f;
        for (int t = 0; t < 4; ++t)
          if (inside(target[t].x(), target[t].y(), target[t].z())) total += weight[t];
        if (total <= 0.0f) continue;
        const float scale = residual / total;
        for (int t = 0; t < 4; ++t)
          if (inside(target[t].x(), target[t].y(), target[t].z()))
            error[index(target[t].x(), target[t].y(), target[t].z())] += weight[t] * scale;
        if (up) error[index(i, j, k + 1)] += share * scale;
      }
    }
  return material;
}

// The voxels where `a` and `b` differ in activity or material.
std::size_t differences(const openvdb::BoolGrid& a, const openvdb::BoolGrid& b) {
  std::size_t wrong = 0;
  const auto bAcc = b.getConstAccessor();
  for (auto it = a.cbeginValueOn(); it; ++it) wrong += !bAcc.isValueOn(it.getCoord()) || bAcc.getValue(it.getCoord()) != *it;
  return wrong + (a.activeVoxelCount() != b.activeVoxelCount() ? 1 : 0);
}

// Layers [k0, k1) of `grid`.
openvdb::FloatGrid::Ptr layersOf(const openvdb::FloatGrid& grid, int k0, int k1) {
  auto band = openvdb::FloatGrid::create(0.0f);
  band->setTransform(grid.transform().copy());
  band->setName(grid.getName());
  auto acc = band->getAccessor();
  for (auto it = grid.cbeginValueOn(); it; ++it)
    if (it.getCoord().z() >= k0 && it.getCoord().z() < k1) acc.setValueOn(it.getCoord(), *it);
  return band;
}

}  // namespace

TEST_CASE("materials: error diffusion follows the single sweep of its definition voxel for voxel", "[materials][dither]") {
  // Straddling the origin (negative coordinates, leaf faces in every direction), rows of a few runs.
  const openvdb::CoordBBox box(openvdb::Coord(-21, -9, -13), openvdb::Coord(26, 14, 20));
  for (std::uint32_t shape : {1u, 2u}) {
    const auto part = irregularPart(box, shape);
    const std::uint64_t seed = 40 + shape;
    const auto reference = referenceSweep(*part, seed);
    REQUIRE(reference->activeVoxelCount() == part->activeVoxelCount());
    for (int workers : {1, 2, 4}) {
      INFO("shape " << shape << ", " << workers << " workers");
      tbb::task_arena arena(workers);
      CHECK(differences(*arena.execute([&] { return makeDitherer("error-diffusion", {seed, nullptr})->dither(*part); }),
                        *reference) == 0);
      // Streamed in bands of 5 layers (not a leaf's 8), each from a grid of the band and one layer more.
      // Each band's output is let go before the next, whose leaves are then the earlier bands' leaves
      // reused: none may keep an earlier band's Vero on a voxel outside the band's layers.
      const auto ditherer = makeDitherer("error-diffusion", {seed, nullptr});
      auto merged = openvdb::BoolGrid::create(false);
      std::size_t staleVero = 0;
      for (int k0 = box.min().z(); k0 <= box.max().z(); k0 += 5) {
        const auto piece = arena.execute([&] { return ditherer->ditherLayers(*layersOf(*part, k0, k0 + 6), k0, k0 + 5); });
        for (auto it = piece->cbeginValueOn(); it; ++it) merged->tree().setValueOn(it.getCoord(), *it);
        for (auto leaf = piece->tree().cbeginLeaf(); leaf; ++leaf)
          for (openvdb::Index n = 0; n < leaf->SIZE; ++n) staleVero += !leaf->isValueOn(n) && leaf->getValue(n);
      }
      CHECK(differences(*merged, *reference) == 0);
      CHECK(staleVero == 0);
    }
  }
}

TEST_CASE("materials: error diffusion of a single row and of isolated voxels", "[materials][dither]") {
  // A row of 1 .. 3 voxels, and voxels with no neighbour after them in any direction: their error has
  // nowhere to go, and each decides alone.
  auto grid = openvdb::FloatGrid::create(0.0f);
  grid->setName(kFractionGridName);
  auto acc = grid->getAccessor();
  for (int n = 0; n < 3; ++n) acc.setValueOn(openvdb::Coord(n, 0, 0), 0.5f);
  acc.setValueOn(openvdb::Coord(10, 10, 3), 0.7f);
  acc.setValueOn(openvdb::Coord(-30, 4, 9), 0.2f);
  acc.setValueOn(openvdb::Coord(12, 10, 3), 1.0f);
  const auto reference = referenceSweep(*grid, 9);
  CHECK(differences(*makeDitherer("error-diffusion", {9, nullptr})->dither(*grid), *reference) == 0);
  const auto material = reference->getConstAccessor();
  CHECK(material.getValue(openvdb::Coord(10, 10, 3)));   // 0.7 alone: above any threshold
  CHECK_FALSE(material.getValue(openvdb::Coord(-30, 4, 9)));  // 0.2 alone: below any
  CHECK(material.getValue(openvdb::Coord(12, 10, 3)));
}

namespace {

using rodfab::tests::heapBytesInUse;

}  // namespace

TEST_CASE("materials: error diffusion's workingBytes bounds the heap it holds while dithering and keeps between bands",
          "[materials][dither][memory]") {
#if defined(__SANITIZE_ADDRESS__)
  WARN("AddressSanitizer keeps its own heap: mallinfo2 does not see it, nothing to measure");
  return;
#endif
  // The truth is glibc's count of the bytes in use: sampled from the workers before every layer (the
  // ditherer's interrupt hook) against the heap before the band, less the band's output grid; and what
  // is left once the ditherer is gone (its slots and carried error), every output still held.
  const openvdb::CoordBBox box(openvdb::Coord(0), openvdb::Coord(383, 191, 39));  // 384 x 192 voxels a layer
  auto fraction = openvdb::FloatGrid::create(0.0f);
  fraction->setName(kFractionGridName);
  fraction->tree().denseFill(box, 0.37f, true);
  fraction->tree().voxelizeActiveTiles();
  constexpr int kBandLayers = 8;
  const double layerVoxels = 384.0 * 192.0;
  const double bandLeaves = 48.0 * 24.0 * 2.0;  // a band's leaves and the next layer's: two slabs
  for (const int concurrency : {1, 2, 4}) {
    INFO("arena of " << concurrency);
    tbb::task_arena arena(concurrency);
    arena.execute([&] {
      std::atomic<std::uint64_t> peak{0};
      const auto sample = [&] {
        const std::uint64_t now = heapBytesInUse();
        for (std::uint64_t seen = peak.load(); now > seen && !peak.compare_exchange_weak(seen, now);) {
        }
      };
      std::vector<openvdb::BoolGrid::Ptr> outputs;  // held: no output tree goes back to the recycler
      const std::uint64_t before = heapBytesInUse();
      auto ditherer = std::make_unique<ErrorDiffusionDitherer>(7, sample);
      const double bound = ditherer->workingBytes({layerVoxels, bandLeaves, kBandLayers}, tbb::this_task_arena::max_concurrency());
      double mostDuring = 0.0;
      for (int k0 = 0; k0 < 40; k0 += kBandLayers) {
        const std::uint64_t start = heapBytesInUse();
        peak = start;
        outputs.push_back(ditherer->ditherLayers(*fraction, k0, k0 + kBandLayers));
        const double output = 1.2 * double(outputs.back()->memUsage());  // its leaves, nodes and their headers
        mostDuring = std::max(mostDuring, double(peak.load()) - double(start) - output);
      }
      const std::uint64_t withDitherer = heapBytesInUse();
      ditherer.reset();
      const double kept = double(withDitherer) - double(heapBytesInUse());
      CAPTURE(before, bound, mostDuring, kept);
      REQUIRE(kept > 0.3 * bound);  // the slots are there, and make up most of the bound
      REQUIRE(bound >= kept);
      REQUIRE(bound >= mostDuring);
    });
  }
}

TEST_CASE("materials: what each ditherer says of itself: the next layer, and working bytes from its buffers", "[materials][dither][memory]") {
  const DitherBand band{1e6, 5e4, 8};
  const auto ed = makeDitherer("error-diffusion");
  CHECK(ed->readsNextLayer());
  // A slot: 27 bytes a voxel of arrays with 1/8 headroom and a float of error; rows of 12 bytes, twice
  // over, at most 8 a leaf (4e5 here, fewer than the voxels); a 16-byte word a leaf.
  const double slot = 27 * 1.125e6 + 4e6 + 24 * 4e5 + 16 * 5e4;
  // 5 slots (2 workers + 3), the carried error (12 bytes a voxel), two workers' masks and the lists.
  CHECK(ed->workingBytes(band, 2) == Approx(5 * slot + 12e6 + 5e4 * (2 * 64 + 40)));
  CHECK(ed->workingBytes(band, 64) == ed->workingBytes(band, 4));  // at most 4 workers
  CHECK(ed->workingBytes(band, 0) == ed->workingBytes(band, 1));
  CHECK(ed->workingBytes({1e6, 5e4, 1}, 4) == Approx(2 * slot + 12e6 + 5e4 * (4 * 64 + 40)));  // a 1-layer band: 2 slots
  // Rows at most one a voxel when the leaves would allow more.
  CHECK(ed->workingBytes({1e4, 5e4, 8}, 1) == Approx(4 * (27 * 1.125e4 + 4e4 + 24 * 1e4 + 16 * 5e4) + 12e4 + 5e4 * (64 + 40)));
  for (const char* pointwise : {"white", "blue"}) {
    INFO(pointwise);
    const auto d = makeDitherer(pointwise);
    CHECK_FALSE(d->readsNextLayer());
    CHECK(d->workingBytes(band, 4) == d->workingBytes(band, 1));  // nothing per worker
    CHECK(d->workingBytes(band, 4) >= 16 * 5e4);
    CHECK(d->workingBytes(band, 4) < 2e6);
  }
}
