// materials/: the white-noise generator (counter_hash.hpp) is uniform and its neighbours independent,
// and the "white" ditherer follows it voxel for voxel, also when streamed bands reuse earlier outputs' nodes.
#include "materials/counter_hash.hpp"
#include "materials/materials.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

using namespace rodfab::materials;

namespace {

// The white-noise number of voxel c: its leaf's key and its offset in the leaf, spelt out from the
// definition (8^3 leaves on a lattice through the origin, offset x * 64 + y * 8 + z).
float whiteAt(std::uint64_t seed, const openvdb::Coord& c) {
  const auto leafOrigin = [](int v) { return static_cast<int>(std::floor(v / 8.0)) * 8; };
  const int x = leafOrigin(c.x()), y = leafOrigin(c.y()), z = leafOrigin(c.z());
  const auto offset = static_cast<std::uint32_t>((c.x() - x) * 64 + (c.y() - y) * 8 + (c.z() - z));
  return whiteNoiseUniform(whiteNoiseLeafKey(seed, x, y, z), offset);
}

// A box of 96 x 40 x 136 voxels (522 k, 12 x 5 x 17 leaves) straddling the origin, so neighbours
// cross leaf faces and negative coordinates.
const openvdb::CoordBBox kBox(openvdb::Coord(-48, -16, -72), openvdb::Coord(47, 23, 63));

std::vector<float> whiteOverBox(std::uint64_t seed) {
  std::vector<float> u;
  for (auto it = kBox.begin(); it; ++it) u.push_back(whiteAt(seed, *it));
  return u;
}

std::size_t boxIndex(const openvdb::Coord& c) {
  const openvdb::Coord d = kBox.dim(), p = c - kBox.min();
  return (static_cast<std::size_t>(p.x()) * d.y() + p.y()) * d.z() + p.z();  // CoordBBox iterates z fastest
}

// Pearson's chi-square statistic of `counts` against equal expected counts.
double chiSquare(const std::vector<double>& counts) {
  double total = 0;
  for (double c : counts) total += c;
  const double expected = total / static_cast<double>(counts.size());
  double chi2 = 0;
  for (double c : counts) chi2 += (c - expected) * (c - expected) / expected;
  return chi2;
}

// Bounds for a chi-square with `dof` degrees of freedom, five standard deviations (sqrt(2 dof)) out:
// a sound generator lands inside, a biased or too regular one outside.
bool chiSquarePlausible(double chi2, double dof) { return std::abs(chi2 - dof) < 5 * std::sqrt(2 * dof); }

}  // namespace

TEST_CASE("materials: white noise is uniform in its high and low bits", "[materials][noise]") {
  for (std::uint64_t seed : {0ull, 1ull, 0x123456789abcdefull}) {
    INFO("seed " << seed);
    const std::vector<float> u = whiteOverBox(seed);
    std::vector<double> high(256, 0.0), low(256, 0.0);
    double sum = 0;
    for (float v : u) {
      REQUIRE((v >= 0.0f && v < 1.0f));
      const auto bits24 = static_cast<std::uint32_t>(v * 0x1p24f);
      REQUIRE(static_cast<float>(bits24) == v * 0x1p24f);  // on the 2^-24 grid
      high[bits24 >> 16] += 1;
      low[bits24 & 255] += 1;
      sum += v;
    }
    CHECK(chiSquarePlausible(chiSquare(high), 255));
    CHECK(chiSquarePlausible(chiSquare(low), 255));
    // Mean 1/2 - 2^-25 with standard deviation sqrt(1/12 / n).
    CHECK(std::abs(sum / static_cast<double>(u.size()) - 0.5) < 5 * std::sqrt(1.0 / 12 / static_cast<double>(u.size())));
  }
}

TEST_CASE("materials: white noise at neighbouring voxels and leaves is independent", "[materials][noise]") {
  const std::vector<float> u = whiteOverBox(7);
  const std::array<openvdb::Coord, 4> steps{openvdb::Coord(1, 0, 0), openvdb::Coord(0, 1, 0), openvdb::Coord(0, 0, 1),
                                            openvdb::Coord(8, 0, 0)};  // the same offset in the next leaf
  for (const openvdb::Coord& step : steps) {
    INFO("step " << step);
    // Correlation and a 16 x 16 joint histogram of the pairs (v, v + step) inside the box.
    double sxy = 0, sx = 0, sy = 0, sxx = 0, syy = 0, n = 0;
    std::vector<double> joint(256, 0.0);
    for (auto it = kBox.begin(); it; ++it) {
      const openvdb::Coord next = *it + step;
      if (!kBox.isInside(next)) continue;
      const double a = u[boxIndex(*it)], b = u[boxIndex(next)];
      sxy += a * b, sx += a, sy += b, sxx += a * a, syy += b * b, n += 1;
      joint[static_cast<std::size_t>(a * 16) * 16 + static_cast<std::size_t>(b * 16)] += 1;
    }
    const double r = (sxy / n - sx / n * sy / n) / std::sqrt((sxx / n - sx * sx / n / n) * (syy / n - sy * sy / n / n));
    CHECK(std::abs(r) < 5 / std::sqrt(n));  // the standard deviation of r is 1 / sqrt(n) for independent pairs
    CHECK(chiSquarePlausible(chiSquare(joint), 255));
  }
  // Another seed gives unrelated numbers at the same voxels.
  const std::vector<float> other = whiteOverBox(8);
  std::size_t same = 0;
  for (std::size_t i = 0; i < u.size(); ++i) same += u[i] == other[i];
  CHECK(same < 10);  // expected u.size() / 2^24 = 0.03
}

TEST_CASE("materials: the white ditherer is the white-noise number against the fraction, voxel by voxel", "[materials][noise]") {
  auto grid = openvdb::FloatGrid::create(0.0f);
  for (auto it = kBox.begin(); it; ++it) {
    const openvdb::Coord c = *it;
    if ((c.x() + 2 * c.y() + 3 * c.z()) % 5 == 0) continue;  // partly filled leaves
    grid->tree().setValueOn(c, static_cast<float>(0.5 + 0.45 * std::sin(0.1 * c.x() + 0.07 * c.y() - 0.05 * c.z())));
  }
  const auto material = makeDitherer("white", {21, nullptr})->dither(*grid);
  REQUIRE(material->activeVoxelCount() == grid->activeVoxelCount());
  const auto m = material->getConstAccessor();
  std::size_t wrong = 0;
  for (auto it = grid->cbeginValueOn(); it; ++it) wrong += m.getValue(it.getCoord()) != (whiteAt(21, it.getCoord()) < *it);
  CHECK(wrong == 0);
}

TEST_CASE("materials: streamed bands reuse earlier outputs' nodes and stay exact, whatever the owners did to them", "[materials][noise]") {
  auto grid = openvdb::FloatGrid::create(0.0f);
  for (auto it = kBox.begin(); it; ++it) {
    const openvdb::Coord c = *it;
    if ((c.x() * c.x() + 3 * c.y() + c.z()) % 7 == 0) continue;  // partly filled leaves
    grid->tree().setValueOn(c, static_cast<float>(0.5 + 0.45 * std::cos(0.09 * c.x() - 0.11 * c.y() + 0.06 * c.z())));
  }
  const auto blueWhole = makeDitherer("blue", {21, nullptr})->dither(*grid);
  for (const char* method : {"white", "blue"}) {
    // Bands of 8 layers on leaf boundaries, then of 5 and 11 (leaves cut by the band).
    for (int bandLayers : {8, 5, 11}) {
      INFO(method << ", bands of " << bandLayers << " layers");
      const auto ditherer = makeDitherer(method, {21, nullptr});
      openvdb::BoolGrid::Ptr kept;  // one output alive while the next is made, as in the slicer
      std::size_t wrong = 0, wrongCounts = 0;
      for (int k0 = kBox.min().z(); k0 <= kBox.max().z(); k0 += bandLayers) {
        const int k1 = std::min(k0 + bandLayers, kBox.max().z() + 1);
        const auto material = ditherer->ditherLayers(*grid, k0, k1);
        const auto m = material->getConstAccessor();
        const auto blue = blueWhole->getConstAccessor();
        openvdb::Index64 bandVoxels = 0;
        for (auto it = grid->cbeginValueOn(); it; ++it) {
          const openvdb::Coord c = it.getCoord();
          if (c.z() < k0 || c.z() >= k1) continue;
          const bool truth = std::string(method) == "white" ? whiteAt(21, c) < *it : blue.getValue(c);
          wrong += !m.isValueOn(c) || m.getValue(c) != truth;
          ++bandVoxels;
        }
        wrongCounts += material->activeVoxelCount() != bandVoxels;  // nothing outside the band
        // An owner that changes the tree before letting it go: a voxel, a tile and values elsewhere.
        material->tree().setValueOn(openvdb::Coord(1000, 1000, k0), true);
        material->tree().addTile(1, openvdb::Coord(0, 0, 4096), true, true);
        material->tree().setValueOff(openvdb::Coord(kBox.min().x(), kBox.min().y(), k0), true);
        kept = material;
      }
      CHECK(wrong == 0);
      CHECK(wrongCounts == 0);
    }
  }
}
