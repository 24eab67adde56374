// One band of a benchmark class, rasterized (and optionally mapped) on one thread, for instruction
// counts under callgrind and for checking that a change leaves the values bit-identical:
//   raster_band CLASS K0 K1 [map]
// prints the band's active voxels, exact evaluations and a checksum (FNV-1a over every active voxel's
// coordinate and value bits, leaves in coordinate order) of the modulus grid, and of the fraction grid
// with `map`, at the voxel of the benchmark profile (bench_profile.hpp). Profile with
//   valgrind --tool=callgrind --toggle-collect='rodfab::voxel::Rasterizer::rasterizeLayers(int, int) const'
//     --toggle-collect='rodfab::materials::mapToFractions(*' build/bench/raster_band lattice 1500 1532 map
#include "bench/bench_profile.hpp"
#include "calibration/calibration_file.hpp"
#include "examples/example_designs.hpp"
#include "materials/fraction_map.hpp"
#include "voxel/voxel.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

std::uint64_t checksum(const openvdb::FloatGrid& grid) {
  std::vector<const openvdb::FloatTree::LeafNodeType*> leaves;
  for (auto it = grid.tree().cbeginLeaf(); it; ++it) leaves.push_back(it.getLeaf());
  std::sort(leaves.begin(), leaves.end(), [](auto* a, auto* b) { return a->origin() < b->origin(); });
  std::uint64_t h = 1469598103934665603ull;
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
    std::fprintf(stderr, "usage: raster_band CLASS K0 K1 [map]\n");
    return 2;
  }
  openvdb::initialize();
  const rodfab::geometry::RodStructure structure = rodfab::examples::benchmarkDesign(argv[1]);
  const rodfab::voxel::PrinterGrid grid = rodfab::voxel::makePrinterGrid(structure, rodfab::bench::benchVoxelMm());
  const int k0 = std::stoi(argv[2]), k1 = std::stoi(argv[3]);
  const rodfab::voxel::Rasterizer rasterizer(structure, grid, {1});
  const rodfab::voxel::Rasterization r = rasterizer.rasterizeLayers(k0, k1);
  std::printf("active %llu exact %llu modulus %016llx\n", static_cast<unsigned long long>(r.grid->activeVoxelCount()),
              static_cast<unsigned long long>(r.exactEvaluations), static_cast<unsigned long long>(checksum(*r.grid)));
  if (argc > 4 && std::strcmp(argv[4], "map") == 0) {
    const rodfab::materials::FractionMap map(rodfab::calibration::loadDefaultCalibration());
    rodfab::materials::MappingStats stats;
    const openvdb::FloatGrid::Ptr fractions = rodfab::materials::mapToFractions(*r.grid, map, k0, k1, stats);
    std::printf("fractions %016llx\n", static_cast<unsigned long long>(checksum(*fractions)));
  }
  return 0;
}
