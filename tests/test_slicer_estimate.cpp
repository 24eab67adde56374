// The slice estimate's parts against what is really held: the trees the recyclers keep (against the
// heap) and RasterProfile's one pass for every band size.

#include "slicer_test_support.hpp"
#include "tests/heap_in_use.hpp"

#include "voxel/tree_assembly.hpp"

#include <deque>

using namespace rodfab;
using namespace slicer_test;

namespace {

using rodfab::tests::heapBytesInUse;

struct StreamedHeap {
  std::uint64_t peak = 0;        // the most in use while bands stream (two in flight)
  std::uint64_t full = 0;        // with both recyclers full while two bands are alive
  std::size_t keptFractions = 0; // the fraction recycler's keptTrees()
};

// Streams `design`'s bands of `bandLayers` as sliceDesign does (two in flight; a band's fractions let go
// once "dithered", its moduli once "written"), the fractions' recycler keeping `keptFractionTrees`, then
// makes and lets go more bands while two are alive, so both recyclers are full. Bytes above the heap
// in use before.
StreamedHeap streamBands(const geometry::RodStructure& design, const voxel::PrinterGrid& grid, int bandLayers, std::size_t keptFractionTrees) {
  const materials::FractionMap map(calibration::loadDefaultCalibration());
  const std::uint64_t before = heapBytesInUse();
  const auto heap = [&] { return heapBytesInUse() - std::min(before, heapBytesInUse()); };
  StreamedHeap out;
  const voxel::Rasterizer rasterizer(design, grid, {2});
  voxel::TreeRecycler<openvdb::FloatTree> fractionTrees(0.0f, keptFractionTrees);
  out.keptFractions = fractionTrees.keptTrees();
  materials::MappingStats stats;
  struct Band {
    openvdb::FloatGrid::Ptr moduli, fractions;
  };
  const auto make = [&](int k0) {
    Band band{rasterizer.rasterizeLayers(k0, k0 + bandLayers).grid, nullptr};
    out.peak = std::max(out.peak, heap());
    band.fractions = materials::mapToFractions(*band.moduli, map, k0, k0 + bandLayers, stats, fractionTrees);
    out.peak = std::max(out.peak, heap());
    return band;
  };
  std::deque<Band> alive;
  int k0 = 0;
  for (; k0 + 5 * bandLayers < grid.dims.z(); k0 += bandLayers) {
    if (alive.size() == std::size_t{slicer::kBandsInFlight}) alive.pop_front();
    alive.push_back(make(k0));
    alive.back().fractions.reset();
  }
  // Enough bands made while two are alive, then let go at once, to fill both recyclers.
  const std::size_t fill = std::max(keptFractionTrees, voxel::TreeRecycler<openvdb::FloatTree>::kKeptTrees);
  REQUIRE(k0 + int(fill) * bandLayers < grid.dims.z());
  std::vector<Band> extra;
  for (std::size_t n = 0; n < fill; ++n) extra.push_back(make(k0 + int(n) * bandLayers));
  extra.clear();
  out.full = heap();
  out.peak = std::max(out.peak, out.full);
  return out;
}

}  // namespace

TEST_CASE("the slice estimate counts the trees the recyclers really keep - 0, 1 and 3 kept fraction trees against the heap",
          "[memory]") {
#if defined(__SANITIZE_ADDRESS__)
  WARN("AddressSanitizer keeps its own heap: mallinfo2 does not see it, nothing to measure");
  return;
#endif
  openvdb::initialize();
  // A 4 mm post with round caps and a 1.5 mm strut, streamed in bands of 16 layers.
  const geometry::NurbsCurve post(1, {0, 0, 1, 1}, {geometry::Vec3(5, 5, 0.5), geometry::Vec3(5, 5, 7.5)});
  const geometry::NurbsCurve strut(1, {0, 0, 1, 1}, {geometry::Vec3(3, 4, 1), geometry::Vec3(8, 7, 7)});
  const geometry::RodStructure design{
      "kept", {geometry::Rod("post", post, geometry::Section::circle(4.0), std::nullopt, std::nullopt, geometry::CapStyle::Round,
                             geometry::BSplineField::constant(20, 0, 1)),
               geometry::Rod("strut", strut, geometry::Section::circle(1.5), std::nullopt, std::nullopt, geometry::CapStyle::Flat,
                             geometry::BSplineField(1, {0, 0, 1, 1}, {2.0, 150.0}))}};
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, connex3().voxelSize());
  constexpr int kBandLayers = 16;
  // streamBands' bands hold their own layers only (as the white and blue ditherers' do): the tighter
  // estimate without the next layer is the one to bound them.
  const voxel::RasterEstimate estimate = voxel::RasterProfile(design, grid).estimate(kBandLayers, false);
  const tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
  const std::size_t keptModuli = voxel::TreeRecycler<openvdb::FloatTree>::kKeptTrees;  // the Rasterizer's recycler
  std::vector<std::pair<double, StreamedHeap>> runs;  // (estimate, heap)
  for (const std::size_t kept : {std::size_t{0}, std::size_t{1}, std::size_t{3}}) {
    INFO("kept fraction trees " << kept);
    const StreamedHeap heap = streamBands(design, grid, kBandLayers, kept);
    REQUIRE(heap.keptFractions == kept);
    const double bound = estimate.peakBytes(slicer::kBandsInFlight, keptModuli + kept);
    CAPTURE(heap.peak, heap.full, estimate.bandBytes, bound);
    CHECK(bound >= double(heap.peak));
    runs.emplace_back(bound, heap);
  }
  // Three kept trees more hold three band trees more, on the heap and in the estimate; the estimate
  // grows by at least what the heap does (an estimate blind to the count would not grow at all).
  const double heapGrowth = double(runs[2].second.full) - double(runs[0].second.full);
  const double estimateGrowth = runs[2].first - runs[0].first;
  CAPTURE(heapGrowth, estimateGrowth);
  CHECK(heapGrowth > 3 * 100'000.0);  // the kept trees are there: each band's grid holds hundreds of leaves
  CHECK(estimateGrowth >= heapGrowth);
  CHECK(runs[1].first > runs[0].first);
}

// estimateRaster is RasterProfile's estimate of one band size (the real grids are the truth the single-rod
// test above checks); here what a profile must keep across band sizes.
TEST_CASE("RasterProfile: every band size's estimate from one pass: the design's figures the same, no fewer leaves in larger bands",
          "[voxel][estimate][memory]") {
  openvdb::initialize();
  for (const char* name : {"arm-cast", "unfolding-box"}) {
    INFO(name);
    const geometry::RodStructure design = geometry::readDesign(fs::path("examples") / (std::string(name) + ".json"));
    const voxel::PrinterGrid grid = voxel::makePrinterGrid(design, connex3().voxelSize());
    const voxel::RasterProfile profile(design, grid);
    const voxel::RasterEstimate whole = profile.estimate(0);
    double previousLeaves = 0.0;
    for (const int bandLayers : {1, 2, 4, 8, 16, 40, 64, 100'000}) {
      INFO("band layers " << bandLayers);
      const voxel::RasterEstimate once = profile.estimate(bandLayers);
      CHECK(once.maxPieces == whole.maxPieces);
      CHECK(once.pieceBytes == whole.pieceBytes);
      CHECK(once.activeVoxels == whole.activeVoxels);
      CHECK(once.leaves == whole.leaves);
      CHECK(once.gridBytes == whole.gridBytes);
      // Bands of 1, 2 and 4 layers stay within one slab (slicer::bandEnd): the leaves of an 8-layer band.
      if (bandLayers < 8) CHECK(once.bandLeaves == profile.estimate(8).bandLeaves);
      if (bandLayers < 8) CHECK(profile.estimate(bandLayers, false).bandLeaves == profile.estimate(8, false).bandLeaves);
      CHECK(once.bandLeaves >= previousLeaves);  // larger bands hold no fewer leaves
      previousLeaves = once.bandLeaves;
      if (bandLayers > 0) CHECK(once.bandLeaves > 0.0);
    }
    CHECK(profile.estimate(100'000).bandLeaves == Approx(profile.estimate(0).leaves).epsilon(1e-4));  // a band of the whole part (sums of spread shares)
  }
}
