// One band of a benchmark class, rasterized (and optionally mapped) on one thread, for instruction
// counts under callgrind and for checking that a change leaves the values bit-identical:
//   raster_band CLASS K0 K1 [map] [threads=N] [bands=L]
// prints the band's active voxels, exact evaluations and a checksum (FNV-1a over every active voxel's
// coordinate and value bits, leaves in coordinate order) of the modulus grid, and of the fraction grid
// with `map`, at the voxel of the benchmark profile (bench_profile.hpp), then the rasterizer's piece
// count (a line "pieces N"). With bands=L the layers go through in bands of L (as the slicer streams
// them; the checksums then run over the bands in order, so a whole class fits in memory), with
// threads=N on N TBB workers (default 1). As in `rodfab slice`, the rasterizer and the mapping each
// build a band's tree from the nodes of the trees let go before (voxel::TreeRecycler), so a run of
// several bands also counts what the reuse costs (TreeRecycler::takeSpares). Profile with
//   valgrind --tool=callgrind --toggle-collect='rodfab::voxel::Rasterizer::rasterizeLayers(int, int) const'
//     --toggle-collect='rodfab::materials::mapToFractions(*' build/bench/raster_band lattice 1500 1532 map
#include "bench/bench_profile.hpp"
#include "calibration/calibration_file.hpp"
#include "examples/example_designs.hpp"
#include "materials/fraction_map.hpp"
#include "voxel/tree_assembly.hpp"
#include "voxel/voxel.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

constexpr std::uint64_t kChecksumSeed = 1469598103934665603ull;

// Continues the checksum h over the grid's active voxels.
std::uint64_t checksum(const openvdb::FloatGrid& grid, std::uint64_t h = kChecksumSeed) {
  std::vector<const openvdb::FloatTree::LeafNodeType*> leaves;
  for (auto it = grid.tree().cbeginLeaf(); it; ++it) leaves.push_back(it.getLeaf());
  std::sort(leaves.begin(), leaves.end(), [](auto* a, auto* b) { return a->origin() < b->origin(); });
  const auto mix = [&h](std::uint32_t v) {
    for (int b = 0; b < 4; ++b) h = (h ^ ((v >> (8 * b)) & 0xffu)) * 1099511628211ull;
  };
  for (auto* leaf : leaves)
    for (auto v = leaf->cbeginValueOn(); v; ++v) {
      const openvdb::Coord c = v.getCoord();
      mix(std::uint32_t(c.x()));
      mix(std::uint32_t(c.y()));
      mix(std::uint32_t(c.z()));
      mix(std::bit_cast<std::uint32_t>(*v));
    }
  return h;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: raster_band CLASS K0 K1 [map] [threads=N] [bands=L]\n");
    return 2;
  }
  bool map = false;
  int threads = 1, bandLayers = 0;
  for (int a = 4; a < argc; ++a) {
    if (std::strcmp(argv[a], "map") == 0) map = true;
    else if (std::strncmp(argv[a], "threads=", 8) == 0) threads = std::stoi(argv[a] + 8);
    else if (std::strncmp(argv[a], "bands=", 6) == 0) bandLayers = std::stoi(argv[a] + 6);
    else {
      std::fprintf(stderr, "raster_band: unknown argument '%s'\n", argv[a]);
      return 2;
    }
  }
  openvdb::initialize();
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(std::max(1, threads)));
  const rodfab::geometry::RodStructure structure = rodfab::examples::benchmarkDesign(argv[1]);
  const rodfab::voxel::PrinterGrid grid = rodfab::voxel::makePrinterGrid(structure, rodfab::bench::benchVoxelMm());
  const int k0 = std::stoi(argv[2]), k1 = std::stoi(argv[3]);
  const rodfab::voxel::Rasterizer rasterizer(structure, grid, {threads});
  const rodfab::materials::FractionMap fractionMap(rodfab::calibration::loadDefaultCalibration());
  rodfab::voxel::TreeRecycler<openvdb::FloatTree> fractionTrees(0.0f);
  std::uint64_t active = 0, exact = 0, modulusSum = kChecksumSeed, fractionSum = kChecksumSeed;
  const int step = bandLayers > 0 ? bandLayers : std::max(1, k1 - k0);
  for (int z = k0; z < k1; z += step) {
    const int zEnd = std::min(k1, z + step);
    const rodfab::voxel::Rasterization r = rasterizer.rasterizeLayers(z, zEnd);
    active += r.grid->activeVoxelCount();
    exact += r.exactEvaluations;
    modulusSum = checksum(*r.grid, modulusSum);
    if (!map) continue;
    rodfab::materials::MappingStats stats;
    fractionSum = checksum(*rodfab::materials::mapToFractions(*r.grid, fractionMap, z, zEnd, stats, fractionTrees), fractionSum);
  }
  std::printf("active %llu exact %llu modulus %016llx\n", static_cast<unsigned long long>(active),
              static_cast<unsigned long long>(exact), static_cast<unsigned long long>(modulusSum));
  if (map) std::printf("fractions %016llx\n", static_cast<unsigned long long>(fractionSum));
  std::printf("pieces %zu\n", rasterizer.pieceCount());
  return 0;
}
