// materials/: error diffusion's neighbour links (error_diffusion_layers.hpp), computed run by run, against
// their definition looked up voxel by voxel, on random layers from single scattered voxels to full rows.
#include "materials/error_diffusion_layers.hpp"

#include <catch2/catch.hpp>

#include <array>
#include <cstdint>
#include <map>
#include <random>
#include <set>
#include <utility>
#include <vector>

using namespace rodfab::materials::detail;

namespace {

// A layer's rows: j -> the x of its voxels (ascending).
using RowSets = std::map<int, std::set<int>>;

// Random rows over x in [-70, 70): some j missing, and each row's density drawn from scattered voxels
// (runs of one or two) to full rows, so runs start and end at every offset from the next row's.
RowSets randomRows(std::mt19937& random, int j0, int rows) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  RowSets sets;
  for (int j = j0; j < j0 + rows; ++j) {
    if (unit(random) < 0.15) continue;
    const double density = std::array<double, 5>{0.05, 0.3, 0.7, 0.95, 1.0}[random() % 5];
    std::set<int>& row = sets[j];
    for (int x = -70; x < 70; ++x)
      if (unit(random) < density) row.insert(x);
    if (row.empty()) sets.erase(j);
  }
  return sets;
}

Layer layerOf(const RowSets& sets) {
  Layer layer;
  std::size_t count = 0;
  for (const auto& [j, row] : sets) count += row.size();
  layer.resize(count);
  std::uint32_t n = 0;
  for (const auto& [j, row] : sets) {
    const std::uint32_t begin = n;
    for (int x : row) layer.i[n++] = x;
    layer.rows.push_back({j, begin, n});
  }
  return layer;
}

// The voxel index of (x, j) in `layer`, kNoVoxel if it is not in the layer.
std::uint32_t indexOf(const Layer& layer, int x, int j) {
  for (const LayerRow& row : layer.rows)
    if (row.j == j)
      for (std::uint32_t v = row.begin; v < row.end; ++v)
        if (layer.i[v] == x) return v;
  return kNoVoxel;
}

// Layer::links' in-layer bits and nextRow of voxel v as error_diffusion_layers.hpp defines them: nextRow
// is the first voxel of row j + 1 at x >= i - 1, that row's end when it has none, 0 without a row j + 1.
std::pair<unsigned, std::uint32_t> expectedWithin(const Layer& layer, const LayerRow& row, std::uint32_t v) {
  const int x = layer.i[v], j = row.j;
  unsigned bits = 0;
  if (indexOf(layer, x - 1, j) != kNoVoxel) bits |= kLeft;
  if (indexOf(layer, x + 1, j) != kNoVoxel) bits |= kRight;
  if (indexOf(layer, x - 1, j + 1) != kNoVoxel) bits |= kNextLeft;
  if (indexOf(layer, x, j + 1) != kNoVoxel) bits |= kNextSame;
  if (indexOf(layer, x + 1, j + 1) != kNoVoxel) bits |= kNextRight;
  std::uint32_t next = 0;
  for (const LayerRow& other : layer.rows)
    if (other.j == j + 1) {
      next = other.end;
      for (std::uint32_t w = other.end; w-- > other.begin;)
        if (layer.i[w] >= x - 1) next = w;
    }
  return {bits, next};
}

}  // namespace

TEST_CASE("materials: error diffusion's run-based links equal their definition voxel by voxel", "[materials][dither]") {
  std::mt19937 random(17);
  for (int trial = 0; trial < 60; ++trial) {
    const int j0 = static_cast<int>(random() % 9) - 4;
    Layer below = layerOf(randomRows(random, j0, 12));
    const Layer above = layerOf(randomRows(random, j0 + static_cast<int>(random() % 5) - 2, 12));
    linkWithinLayer(below);
    linkUp(below, above);
    for (const LayerRow& row : below.rows)
      for (std::uint32_t v = row.begin; v < row.end; ++v) {
        const auto [bits, next] = expectedWithin(below, row, v);
        const std::uint32_t up = indexOf(above, below.i[v], row.j);
        INFO("trial " << trial << ", voxel (" << below.i[v] << ", " << row.j << ")");
        CHECK(below.links[v] == (bits | (up != kNoVoxel ? unsigned{kUp} : 0u)));
        CHECK(below.nextRow[v] == next);
        CHECK(below.up[v] == up);
      }
  }
}

TEST_CASE("materials: error diffusion's links of an empty layer, one voxel, and one full row", "[materials][dither]") {
  Layer empty = layerOf({});
  linkWithinLayer(empty);
  linkUp(empty, empty);
  CHECK(empty.size() == 0);

  Layer one = layerOf({{3, {-1}}});
  linkWithinLayer(one);
  linkUp(one, one);
  CHECK(one.links[0] == kUp);
  CHECK(one.nextRow[0] == 0);
  CHECK(one.up[0] == 0);

  std::set<int> full;
  for (int x = -8; x < 200; ++x) full.insert(x);
  Layer rows = layerOf({{0, full}, {1, full}});
  const Layer above = layerOf({{1, full}});
  linkWithinLayer(rows);
  linkUp(rows, above);
  CHECK(rows.links[0] == (kRight | kNextSame | kNextRight));
  CHECK(rows.links[1] == (kLeft | kRight | kNextLeft | kNextSame | kNextRight));
  CHECK(rows.nextRow[1] == 208);
  CHECK(rows.links[207] == (kLeft | kNextLeft | kNextSame));
  CHECK(rows.up[207] == kNoVoxel);
  CHECK(rows.links[208] == (kRight | kUp));
  CHECK(rows.up[415] == 207);
}
