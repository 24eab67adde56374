// One band of a benchmark class on one thread, for instruction counts under callgrind and for checking
// that a change leaves the grid as it was:
//   raster_band DESIGN K0 K1 [map] [threads=N] [bands=L] [verify=S]
// DESIGN is a benchmark class (spring, lattice, curved-lattice, dense) or a design file (*.json).
// Prints the band's active voxels, exact evaluations and a checksum (FNV-1a over every active voxel's
// coordinate and value bits, leaves in coordinate order) of the modulus grid, and of the fraction grid
// with `map`, at the voxel of the benchmark profile (bench_profile.hpp); a membership checksum (the
// active voxels' coordinates only: equal when the active set is, whatever the values); then the
// rasterizer's piece count (a line "pieces N"). With bands=L the layers go through in bands of L (as the
// slicer streams them; the checksums then run over the bands in order, so a whole class fits in
// memory), with threads=N on N TBB workers (default 1). With verify=S about one active voxel in S
// (picked by a hash of its coordinate) is checked against the exact rule (tests/exact_voxel.hpp: inside,
// and E of the winning rod at its deepest section): the largest relative difference of its value from
// that E is printed, and how many sampled voxels the exact rule puts outside. As in `rodfab slice`, the
// rasterizer and the mapping each build a band's tree from the nodes of the trees let go before
// (voxel::TreeRecycler), so a run of several bands also counts what the reuse costs
// (TreeRecycler::takeSpares). Profile with
//   valgrind --tool=callgrind --toggle-collect='rodfab::voxel::Rasterizer::rasterizeLayers(int, int) const'
//     --toggle-collect='rodfab::materials::mapToFractions(*' build/bench/raster_band lattice 1500 1532 map
#include "bench/bench_profile.hpp"
#include "calibration/calibration_file.hpp"
#include "examples/example_designs.hpp"
#include "geometry/design_file.hpp"
#include "materials/fraction_map.hpp"
#include "tests/exact_voxel.hpp"
#include "voxel/tree_assembly.hpp"
#include "voxel/voxel.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

constexpr std::uint64_t kChecksumSeed = 1469598103934665603ull;

// The grid's active voxels, leaves in coordinate order.
template <typename Visit>
void forEachActive(const openvdb::FloatGrid& grid, Visit visit) {
  std::vector<const openvdb::FloatTree::LeafNodeType*> leaves;
  for (auto it = grid.tree().cbeginLeaf(); it; ++it) leaves.push_back(it.getLeaf());
  std::sort(leaves.begin(), leaves.end(), [](auto* a, auto* b) { return a->origin() < b->origin(); });
  for (auto* leaf : leaves)
    for (auto v = leaf->cbeginValueOn(); v; ++v) visit(v.getCoord(), *v);
}

void mix(std::uint64_t& h, std::uint32_t v) {
  for (int b = 0; b < 4; ++b) h = (h ^ ((v >> (8 * b)) & 0xffu)) * 1099511628211ull;
}

// Continues the checksum h over the grid's active voxels: coordinates and value bits, or (withValues
// false) coordinates only.
std::uint64_t checksum(const openvdb::FloatGrid& grid, std::uint64_t h = kChecksumSeed, bool withValues = true) {
  forEachActive(grid, [&](const openvdb::Coord& c, float value) {
    for (int a = 0; a < 3; ++a) mix(h, std::uint32_t(c[a]));
    if (withValues) mix(h, std::bit_cast<std::uint32_t>(value));
  });
  return h;
}

// The sampled voxels' comparison with the exact rule (verify=S).
struct Verification {
  std::uint64_t sampled = 0, outside = 0;
  double worstRelative = 0.0;
  openvdb::Coord worstAt;
};

// About one active voxel in `stride`, picked by a hash of its coordinate (no alignment with rows or
// leaves), against tests::exactVoxel.
void verify(const rodfab::geometry::RodStructure& structure, const rodfab::voxel::PrinterGrid& printer,
            const openvdb::FloatGrid& grid, std::uint64_t stride, Verification& out) {
  forEachActive(grid, [&](const openvdb::Coord& c, float value) {
    std::uint64_t h = kChecksumSeed;
    for (int a = 0; a < 3; ++a) mix(h, std::uint32_t(c[a]));
    if ((h ^ (h >> 29)) % stride != 0) return;
    ++out.sampled;
    const openvdb::Vec3d p = printer.worldPoint(c);
    const rodfab::test::ExactVoxel e = rodfab::test::exactVoxel(structure, {p.x(), p.y(), p.z()});
    if (!e.inside) {
      ++out.outside;
      return;
    }
    const double relative = std::abs(double(value) - e.value) / std::abs(e.value);
    if (relative > out.worstRelative) out.worstRelative = relative, out.worstAt = c;
  });
}

rodfab::geometry::RodStructure design(const std::string& name) {
  if (name.size() > 5 && name.ends_with(".json")) return rodfab::geometry::readDesign(name);
  return rodfab::examples::benchmarkDesign(name);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: raster_band DESIGN K0 K1 [map] [threads=N] [bands=L] [verify=S]\n");
    return 2;
  }
  bool map = false;
  int threads = 1, bandLayers = 0;
  std::uint64_t verifyStride = 0;
  for (int a = 4; a < argc; ++a) {
    if (std::strcmp(argv[a], "map") == 0) map = true;
    else if (std::strncmp(argv[a], "threads=", 8) == 0) threads = std::stoi(argv[a] + 8);
    else if (std::strncmp(argv[a], "bands=", 6) == 0) bandLayers = std::stoi(argv[a] + 6);
    else if (std::strncmp(argv[a], "verify=", 7) == 0) verifyStride = std::max(1ull, std::stoull(argv[a] + 7));
    else {
      std::fprintf(stderr, "raster_band: unknown argument '%s'\n", argv[a]);
      return 2;
    }
  }
  openvdb::initialize();
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(std::max(1, threads)));
  const rodfab::geometry::RodStructure structure = design(argv[1]);
  const rodfab::voxel::PrinterGrid grid = rodfab::voxel::makePrinterGrid(structure, rodfab::bench::benchVoxelMm());
  const int k0 = std::stoi(argv[2]), k1 = std::min(std::stoi(argv[3]), grid.dims.z());
  const rodfab::voxel::Rasterizer rasterizer(structure, grid, {threads});
  const rodfab::materials::FractionMap fractionMap(rodfab::calibration::loadDefaultCalibration());
  rodfab::voxel::TreeRecycler<openvdb::FloatTree> fractionTrees(0.0f);
  std::uint64_t active = 0, exact = 0, modulusSum = kChecksumSeed, fractionSum = kChecksumSeed, membershipSum = kChecksumSeed;
  Verification verification;
  const int step = bandLayers > 0 ? bandLayers : std::max(1, k1 - k0);
  for (int z = k0; z < k1; z += step) {
    const int zEnd = std::min(k1, z + step);
    const rodfab::voxel::Rasterization r = rasterizer.rasterizeLayers(z, zEnd);
    active += r.grid->activeVoxelCount();
    exact += r.exactEvaluations;
    modulusSum = checksum(*r.grid, modulusSum);
    membershipSum = checksum(*r.grid, membershipSum, false);
    if (verifyStride > 0) verify(structure, grid, *r.grid, verifyStride, verification);
    if (!map) continue;
    rodfab::materials::MappingStats stats;
    fractionSum = checksum(*rodfab::materials::mapToFractions(*r.grid, fractionMap, z, zEnd, stats, fractionTrees), fractionSum);
  }
  std::printf("active %llu exact %llu modulus %016llx\n", static_cast<unsigned long long>(active),
              static_cast<unsigned long long>(exact), static_cast<unsigned long long>(modulusSum));
  if (map) std::printf("fractions %016llx\n", static_cast<unsigned long long>(fractionSum));
  std::printf("membership %016llx\n", static_cast<unsigned long long>(membershipSum));
  if (verifyStride > 0)
    std::printf("verified %llu outside %llu worst relative E difference %.3g at (%d, %d, %d)\n",
                static_cast<unsigned long long>(verification.sampled), static_cast<unsigned long long>(verification.outside),
                verification.worstRelative, verification.worstAt.x(), verification.worstAt.y(), verification.worstAt.z());
  std::printf("pieces %zu\n", rasterizer.pieceCount());
  return 0;
}
