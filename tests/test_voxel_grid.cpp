// voxel/: around the rasterizer: the printer grid, memory (sparse trees, the estimate made before
// rasterizing), grid statistics and .vdb files.
#include "voxel/voxel.hpp"

#include "examples/example_designs.hpp"

#include "tests/file_size_limit.hpp"
#include "tests/voxel_fixture.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

using namespace rodfab;
using namespace rodfab::test;  // with the fixture's geometry and voxel names

TEST_CASE("The printer grid puts cell (0,0,0) one voxel below the bounding box", "[voxel][grid]") {
  const RodStructure s = design({circularRod(line({1, 2, 3}, {4, 2, 3}), 0.5, CapStyle::Flat)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const geometry::Box3 box = s.bounds();
  REQUIRE(g.voxelSize == kTestVoxel);
  for (int a = 0; a < 3; ++a) {
    // Centres at integer indices: cell (0,0,0) spans [origin - v/2, origin + v/2).
    REQUIRE(g.origin[a] - 0.5 * g.voxelSize[a] == Approx(box.min()[a] - g.voxelSize[a]));
    // The last cell lies wholly beyond the box: an empty layer on every side.
    REQUIRE(g.origin[a] + (g.dims[a] - 1.5) * g.voxelSize[a] >= box.max()[a] - 1e-12);
    REQUIRE(g.origin[a] + (g.dims[a] - 2.5) * g.voxelSize[a] < box.max()[a]);
  }
  const openvdb::math::Transform::Ptr t = g.transform();
  const openvdb::Vec3d w = t->indexToWorld(openvdb::Coord(10, 20, 30));
  REQUIRE(w.x() == Approx(g.origin.x() + 10 * 0.0423));
  REQUIRE(w.y() == Approx(g.origin.y() + 20 * 0.0846));
  REQUIRE(w.z() == Approx(g.origin.z() + 30 * 0.030));
  REQUIRE(t->voxelSize().x() == Approx(0.0423));
  REQUIRE(t->voxelSize().z() == Approx(0.030));
}

TEST_CASE("Bad voxel sizes and empty designs are refused with a clear message", "[voxel][grid][errors]") {
  const RodStructure s = design({circularRod(line({0, 0, 0}, {1, 0, 0}), 0.5, CapStyle::Flat)});
  REQUIRE_THROWS_WITH(voxel::makePrinterGrid(s, {0.04, 0.0, 0.03}), Catch::Contains("voxel size") && Catch::Contains("positive"));
  REQUIRE_THROWS_WITH(voxel::makePrinterGrid(s, {0.04, -1, 0.03}), Catch::Contains("positive"));
  REQUIRE_THROWS_WITH(voxel::makePrinterGrid(s, {std::nan(""), 0.1, 0.03}), Catch::Contains("positive"));
  REQUIRE_THROWS_WITH(voxel::makePrinterGrid(design({}), kTestVoxel), Catch::Contains("test: the design has no rods"));
  REQUIRE_THROWS_WITH(voxel::makePrinterGrid(s, {1e-9, 0.1, 0.1}), Catch::Contains("voxels along an axis"));
}

TEST_CASE("Memory follows the active voxels, not the envelope", "[voxel][sparse]") {
  // Two short rods 85 mm apart: a 2000 x 1000 x 3000 voxel envelope (6 gigavoxels) holding ~4,700 voxels.
  const RodStructure s = design({circularRod(line({0, 0, 0}, {0.5, 0, 0}), 0.3, CapStyle::Round),
                                 circularRod(line({84, 84, 89}, {84, 84, 89.5}), 0.3, CapStyle::Round)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  REQUIRE(g.voxelCount() > 5'000'000'000ull);
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  const auto active = ras.grid->activeVoxelCount();
  const double capsule = kPi * 0.09 * 0.5 + 4.0 / 3.0 * kPi * 0.027;
  REQUIRE(double(active) * g.voxelVolume() == Approx(2 * capsule).epsilon(0.04));
  REQUIRE(ras.grid->tree().leafCount() * 512 < 4 * active);
  REQUIRE(ras.grid->memUsage() < 100 * active);
}

TEST_CASE("The memory estimate made before rasterizing bounds the grid OpenVDB builds", "[voxel][sparse][memory]") {
  // OpenVDB's own count of the tree's bytes is the independent truth; the estimate must not fall below
  // it (a refusal would come too late) nor exceed it by so much that fitting designs are refused.
  const Vec3 a(0.1, 0.2, 0.3), dir = Vec3(0.8, 0.5, 0.3).normalized();
  const std::vector<std::pair<std::string, Rod>> rods = {
      {"thick round", circularRod(line(a, a + 4.0 * dir), 1.2, CapStyle::Round)},
      {"thin round", circularRod(line(a, a + 6.0 * dir), 0.1, CapStyle::Flat)},
      {"flat ellipse", Rod("e", line(a, a + 5.0 * dir), Section::ellipse(3.0, 0.05), Vec3(0, 0, 1), std::nullopt,
                           CapStyle::Flat, BSplineField::constant(50, 0, 1))},
      {"rectangle", Rod("r", line(a, a + 5.0 * dir), Section::rectangle(1.5, 0.8), Vec3(0, 0, 1), std::nullopt,
                        CapStyle::Round, BSplineField::constant(50, 0, 1))},
  };
  for (const auto& [name, rod] : rods) {
    CAPTURE(name);
    const RodStructure s = design({rod});
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const double built = double(voxel::rasterize(s, g).grid->memUsage());
    const double estimate = double(voxel::estimateRasterizationBytes(s, g));
    CAPTURE(built, estimate);
    REQUIRE(estimate >= built);
    REQUIRE(estimate <= 3.0 * built);
  }
  SECTION("a part far beyond any memory is estimated without overflow") {
    const RodStructure s = design({circularRod(line({0, 0, 0}, {300, 0, 0}), 75.0, CapStyle::Round)});
    const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
    const double voxels = kPi * 75.0 * 75.0 * 300.0 / g.voxelVolume();
    REQUIRE(double(voxel::estimateRasterizationBytes(s, g)) >= 4.0 * voxels);
  }
}

TEST_CASE("Grid statistics agree with a direct count", "[voxel][statistics]") {
  const BSplineField e(1, {0, 0, 1, 1}, {12.0, 60.0});
  const RodStructure s = design({circularRod(line({0, 0, 0}, {2, 0, 0}), 0.4, CapStyle::Flat, e),
                                 circularRod(line({0, 1, 0}, {0, 1, 2}), 0.3, CapStyle::Round)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  const voxel::GridStatistics st = voxel::computeStatistics(*ras.grid, g, ras.voxelsPerRod);
  std::uint64_t n = 0;
  double sum = 0, lo = 1e9, hi = -1e9;
  openvdb::CoordBBox box;
  for (auto it = ras.grid->cbeginValueOn(); it; ++it, ++n) {
    sum += *it, lo = std::min<double>(lo, *it), hi = std::max<double>(hi, *it);
    box.expand(it.getCoord());
  }
  REQUIRE(st.activeVoxels == n);
  REQUIRE(st.occupiedVolumeMm3 == Approx(n * 0.0423 * 0.0846 * 0.030));
  REQUIRE(st.modulusMin == Approx(lo));
  REQUIRE(st.modulusMax == Approx(hi));
  REQUIRE(st.modulusMean == Approx(sum / n));
  // E rises 24 MPa/mm along x; the outermost voxel centres lie within one voxel of the rod's ends.
  REQUIRE(lo == Approx(12.0).margin(24 * 0.0423));
  REQUIRE(hi == Approx(60.0).margin(24 * 0.0423));
  REQUIRE(st.boundsVoxels == box);
  REQUIRE(st.boundsMinMm.x() == Approx(-0.3).margin(0.0423));  // the second rod's radius; the first ends flat at 0
  REQUIRE(st.boundsMaxMm.z() == Approx(2.3).margin(0.03));
  REQUIRE(st.voxelsPerRod.size() == 2);
  REQUIRE(st.voxelsPerRod[0] + st.voxelsPerRod[1] == n);
  // An axis-aligned rod: within the lattice noise of its section (see the straight-rod test).
  REQUIRE(double(st.voxelsPerRod[0]) * g.voxelVolume() == Approx(kPi * 0.16 * 2).epsilon(0.04));

  const voxel::GridStatistics empty = voxel::computeStatistics(*openvdb::FloatGrid::create(), g);
  REQUIRE(empty.activeVoxels == 0);
  REQUIRE(empty.boundsVoxels.empty());
}

TEST_CASE(".vdb files round-trip and are written atomically", "[voxel][io]") {
  const RodStructure s = design({circularRod(helix(1.0, 1.0, 0.5), 0.3, CapStyle::Round)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const voxel::Rasterization ras = voxel::rasterize(s, g);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "rodfab-test-voxel";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "bend.vdb").string();
  voxel::writeGridFile(path, *ras.grid);
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    REQUIRE(entry.path().filename() == "bend.vdb");  // no temporary left behind
  const openvdb::FloatGrid::Ptr back = voxel::readFloatGrid(path, voxel::kModulusGridName);
  requireIdentical(*ras.grid, *back);
  REQUIRE(back->transform() == ras.grid->transform());

  REQUIRE_THROWS_WITH(voxel::readFloatGrid(path, "density"), Catch::Contains("bend.vdb") && Catch::Contains("density"));
  REQUIRE_THROWS_WITH(voxel::readFloatGrid((dir / "missing.vdb").string(), "modulus_mpa"), Catch::Contains("missing.vdb"));
  REQUIRE_THROWS_WITH(voxel::writeGridFile((dir / "no-such-dir" / "x.vdb").string(), *ras.grid),
                      Catch::Contains("x.vdb: cannot write"));
  std::filesystem::remove_all(dir);
}

namespace {

std::string fileBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_CASE(".vdb files: the same grid gives the same bytes (its UUID from its content), a full disk keeps the old file", "[voxel][io]") {
  const RodStructure s = design({circularRod(helix(1.0, 1.0, 0.5), 0.3, CapStyle::Round)});
  const PrinterGrid g = voxel::makePrinterGrid(s, kTestVoxel);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "rodfab-test-voxel-bytes";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  voxel::writeGridFile((dir / "one.vdb").string(), *voxel::rasterize(s, g, {1}).grid);
  voxel::writeGridFile((dir / "two.vdb").string(), *voxel::rasterize(s, g, {2}).grid);
  const std::string one = fileBytes(dir / "one.vdb");
  REQUIRE(one == fileBytes(dir / "two.vdb"));  // OpenVDB alone writes a random UUID into every file
  // The header's UUID (after the magic, the versions and a flag: 21 bytes) is an RFC 9562 version 8 one,
  // and another grid gets another.
  const std::string uuid = one.substr(21, 36);
  INFO(uuid);
  REQUIRE(std::count(uuid.begin(), uuid.end(), '-') == 4);
  REQUIRE((uuid[8] == '-' && uuid[13] == '-' && uuid[18] == '-' && uuid[23] == '-'));
  REQUIRE(uuid[14] == '8');
  REQUIRE(std::string("89ab").find(uuid[19]) != std::string::npos);
  const RodStructure thicker = design({circularRod(helix(1.0, 1.0, 0.5), 0.35, CapStyle::Round)});
  voxel::writeGridFile((dir / "other.vdb").string(), *voxel::rasterize(thicker, voxel::makePrinterGrid(thicker, kTestVoxel)).grid);
  REQUIRE(fileBytes(dir / "other.vdb").substr(21, 36) != uuid);
  requireIdentical(*voxel::readFloatGrid((dir / "one.vdb").string(), voxel::kModulusGridName), *voxel::rasterize(s, g).grid);

  // The disk fills up while the new grid is written (no file may grow past 4 KiB): an error naming the
  // file, and the old grid as it was, nothing else in the folder.
  REQUIRE(one.size() > 8192);
  {
    const FileSizeLimit full(4096);
    REQUIRE_THROWS_WITH(voxel::writeGridFile((dir / "one.vdb").string(), *voxel::rasterize(thicker, g).grid),
                        Catch::Contains("one.vdb: cannot write the grid") && Catch::Contains("disk full"));
  }
  REQUIRE(fileBytes(dir / "one.vdb") == one);
  std::size_t files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) files += entry.is_regular_file();
  REQUIRE(files == 3);
  std::filesystem::remove_all(dir);
}

TEST_CASE("Rods in different upper nodes: every voxel as the exact test says, the nodes where OpenVDB puts them", "[voxel][grid][tree]") {
  // 180 mm apart along x (an upper node spans 4096 voxels, 173 mm at 0.0423 mm) and 12 mm along y
  // (another leaf parent): the output tree is assembled parent by parent, then upper node by upper node.
  const Rod near = circularRod(line({0, 0, 0}, {0.6, 0.3, 0.4}), 0.25, CapStyle::Round);
  const Rod far = circularRod(line({180, 12, 0.2}, {180.5, 12.2, 0.7}), 0.25, CapStyle::Round);
  const RodStructure both = design({near, far});
  const PrinterGrid g = voxel::makePrinterGrid(both, kTestVoxel);
  const voxel::Rasterization r = voxel::rasterize(both, g);
  std::uint64_t alone = 0;
  for (const Rod& rod : {near, far}) {
    const RodStructure one = design({rod});
    requireMatchesExactTest(one, g, r);  // the pair's grid around this rod (the other is far away)
    alone += voxel::rasterize(one, g).grid->activeVoxelCount();
  }
  REQUIRE(r.grid->activeVoxelCount() == alone);
  REQUIRE(r.grid->tree().root().childCount() == 2);
  // OpenVDB's own assembly of the same leaves, one at a time from the root: the same nodes.
  openvdb::FloatTree byLeaf(0.0f);
  for (auto it = r.grid->tree().cbeginLeaf(); it; ++it) byLeaf.addLeaf(new openvdb::FloatTree::LeafNodeType(*it));
  REQUIRE(byLeaf.hasSameTopology(r.grid->tree()));
  REQUIRE(byLeaf.nodeCount() == r.grid->tree().nodeCount());
}

namespace {

// What an owner may do to a band's grid before letting it go: values and states of voxels changed, an
// active tile in a leaf parent, a tile in an upper node, a leaf's transient data set.
void vandalize(openvdb::FloatGrid& grid) {
  openvdb::FloatTree& tree = grid.tree();
  for (auto leaf = tree.beginLeaf(); leaf; ++leaf) {
    leaf->setValueOff(0, 7.0f);
    leaf->setValueOn(511, -3.0f);
    leaf->setTransientData(99);
  }
  const openvdb::CoordBBox box = grid.evalActiveVoxelBoundingBox();
  if (!box.empty()) {
    tree.addTile(1, box.max().offsetBy(200, 0, 0), 5.0f, true);   // an 8^3 tile in a leaf parent beside the part
    tree.addTile(2, box.max().offsetBy(9000, 0, 0), 2.0f, false);  // a 128^3 tile in an upper node further away
  }
}

// The tree as a fresh one is built: inactive voxels hold the background 0, leaves carry no transient
// data, and there are no tiles.
void requireClean(const openvdb::FloatTree& tree) {
  REQUIRE(!tree.hasActiveTiles());
  std::size_t dirty = 0;
  for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf) {
    dirty += leaf->transientData() != 0;
    for (auto v = leaf->cbeginValueOff(); v; ++v) dirty += *v != 0.0f;
  }
  REQUIRE(dirty == 0);
}

}  // namespace

TEST_CASE("Streamed bands reuse earlier grids' nodes and stay exact, whatever the owners did to them", "[voxel][grid][tree]") {
  // The bundled spring in bands, one band's grid alive while the next is made (as in the slicer), each
  // grid changed by its owner before it is let go: every band as a fresh rasterizer makes it.
  const RodStructure s = examples::bucklingSpring();
  const PrinterGrid g = voxel::makePrinterGrid(s, {0.08, 0.1, 0.06});
  for (int bandLayers : {16, 13}) {
    INFO("bands of " << bandLayers << " layers");
    const voxel::Rasterizer streaming(s, g, {2});
    openvdb::FloatGrid::Ptr kept;
    std::uint64_t total = 0;
    for (int z0 = 0; z0 < g.dims.z(); z0 += bandLayers) {
      const voxel::Rasterization band = streaming.rasterizeLayers(z0, z0 + bandLayers);
      const voxel::Rasterization fresh = voxel::Rasterizer(s, g, {2}).rasterizeLayers(z0, z0 + bandLayers);
      requireIdentical(*band.grid, *fresh.grid);
      REQUIRE(band.grid->tree().hasSameTopology(fresh.grid->tree()));
      REQUIRE(band.grid->tree().nodeCount() == fresh.grid->tree().nodeCount());
      REQUIRE(band.voxelsPerRod == fresh.voxelsPerRod);
      REQUIRE(band.grid->getName() == voxel::kModulusGridName);
      requireClean(band.grid->tree());
      total += band.grid->activeVoxelCount();
      if (kept) vandalize(*kept);
      kept = band.grid;  // the previous band's grid goes back to the rasterizer here
    }
    REQUIRE(total == voxel::rasterize(s, g).grid->activeVoxelCount());
  }
}
