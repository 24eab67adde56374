#include "materials/ditherer.hpp"

#include "common/cpu_clones.hpp"
#include "materials/band_leaves.hpp"
#include "materials/counter_hash.hpp"
#include "materials/error_diffusion.hpp"
#include "materials/fraction_map.hpp"

#include <boost/algorithm/string/join.hpp>

#include <algorithm>
#include <array>
#include <stdexcept>

namespace rodfab::materials {

namespace {

// The rules' leaf kernels are compiled for AVX-512 and AVX2 as well as the baseline, and the loader
// picks by CPU (common/cpu_clones.hpp). Every path gives the same bits: integer arithmetic and float
// comparisons of exactly converted values.
#define RODFAB_CPU_CLONES RODFAB_CLONES("arch=x86-64-v4", "arch=x86-64-v3", "default")

// The white-noise rule for a whole leaf (see detail::ditherPointwise). SplitMix64's 64-bit multiplies
// vectorize only with AVX-512's vpmullq (8 lanes) or, emulated, with AVX2: 0.3 ns a voxel with AVX-512
// where the baseline takes 2.3 to 3.4 ns (GCC's SSE2 emulation, slower than scalar code).
RODFAB_CPU_CLONES
void whiteNoiseLeafBits(std::uint64_t key, const float* values, unsigned words, detail::LeafWords& bits) {
  for (unsigned w = 0; w < detail::LeafMask::WORD_COUNT; ++w) {
    if (!(words >> w & 1u)) continue;
    std::array<std::uint8_t, 64> flags;
    for (std::uint32_t b = 0; b < 64; ++b) flags[b] = whiteNoiseUniform(key, 64 * w + b) < values[64 * w + b];
    bits[w] = detail::packFlags(flags);
  }
}

// The blue-noise rule for a whole leaf: column[x][y] points at the thresholds of the leaf's layers at
// (x, y), 8 consecutive floats; also compiled for AVX-512 and AVX2 (8 or 16 comparisons at once).
using ThresholdColumns = std::array<std::array<const float*, 8>, 8>;
RODFAB_CPU_CLONES
void blueNoiseLeafBits(const ThresholdColumns& column, const float* values, unsigned words, detail::LeafWords& bits) {
  for (unsigned w = 0; w < detail::LeafMask::WORD_COUNT; ++w) {
    if (!(words >> w & 1u)) continue;
    std::array<std::uint8_t, 64> flags;
    for (int y = 0; y < 8; ++y)
      for (int z = 0; z < 8; ++z) flags[8 * y + z] = values[64 * w + 8 * y + z] > column[w][y][z];
    bits[w] = detail::packFlags(flags);
  }
}

// What the pointwise ditherers hold while dithering a band (detail::ditherLeavesInLayers): the band's
// leaves (LeafGroups: a pointer a leaf, and a start index per parent node, fewer) and the output leaves'
// pointers, 8 bytes a leaf each. No buffer per worker or per layer (the fused path's 2 KB of fractions
// a leaf live on the worker's stack), nothing kept between bands but the recycler's spare output nodes
// (the caller counts those with the material trees).
double pointwiseBytes(const DitherBand& band) { return 2.0 * 8.0 * band.leaves; }

// What white and blue noise share: the rule looks at nothing but the voxel, so a band is dithered leaf
// by leaf from its fractions (ditherPointwise) or from its moduli, mapped as it goes
// (mapAndDitherPointwise). `Rules` gives ruleForLeaf(origin) (see ditherPointwise).
template <typename Rules>
class PointwiseDitherer : public Ditherer {
public:
  explicit PointwiseDitherer(std::function<void()> checkInterrupt) : checkInterrupt_(std::move(checkInterrupt)) {}
  bool readsNextLayer() const override { return false; }
  bool mapsWhileDithering() const override { return true; }
  std::size_t keptTrees() const override { return recycler_.keptTrees(); }

protected:
  openvdb::BoolGrid::Ptr ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) override {
    return detail::ditherPointwise(fraction, k0, k1, rules().ruleForLeaf(), recycler_, checkInterrupt_);
  }
  openvdb::BoolGrid::Ptr mapAndDitherLeafVoxels(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                                MappingStats& stats) override {
    return detail::mapAndDitherPointwise(modulus, map, k0, k1, rules().ruleForLeaf(), recycler_, checkInterrupt_, stats);
  }

private:
  const Rules& rules() const { return static_cast<const Rules&>(*this); }
  std::function<void()> checkInterrupt_;  // DitherOptions::checkInterrupt
  detail::OutputTreeRecycler recycler_;
};

// Mezzotint as in the published pipeline: Vero where a uniform number drawn for the voxel is below its
// fraction. The number is a hash of (seed, leaf origin) and the voxel's offset, never a sequential
// stream (counter_hash.hpp).
class WhiteNoiseDitherer final : public PointwiseDitherer<WhiteNoiseDitherer> {
public:
  WhiteNoiseDitherer(std::uint64_t seed, std::function<void()> checkInterrupt)
      : PointwiseDitherer(std::move(checkInterrupt)), seed_(seed) {}
  std::string_view name() const override { return "white"; }
  double workingBytes(const DitherBand& band, int) const override { return pointwiseBytes(band); }

  auto ruleForLeaf() const {
    return [seed = seed_](const openvdb::Coord& origin) {
      const std::uint64_t key = whiteNoiseLeafKey(seed, origin.x(), origin.y(), origin.z());
      return [key](const float* values, unsigned words, detail::LeafWords& bits) { whiteNoiseLeafBits(key, values, words, bits); };
    };
  }

private:
  std::uint64_t seed_;
};

// Ordered dithering with a tiled blue-noise threshold mask; the seed picks where the tiling starts.
class BlueNoiseDitherer final : public PointwiseDitherer<BlueNoiseDitherer> {
public:
  BlueNoiseDitherer(std::shared_ptr<const BlueNoiseMask> mask, std::uint64_t seed, std::function<void()> checkInterrupt)
      : PointwiseDitherer(std::move(checkInterrupt)), mask_(std::move(mask)) {
    const auto r = philox(seed, 0, 0, 0, HashStream::MaskOffset);
    for (int a = 0; a < 3; ++a) offset_[a] = static_cast<int>(r[a] % static_cast<std::uint32_t>(mask_->size()[a]));
    buildColumns();
  }
  std::string_view name() const override { return "blue"; }
  // The leaf lists, and the rearranged thresholds it keeps for good (about 0.8 MB for the bundled mask).
  double workingBytes(const DitherBand& band, int) const override {
    return pointwiseBytes(band) + double(columns_.size() * sizeof(float));
  }

  auto ruleForLeaf() const {
    return [this](const openvdb::Coord& origin) {
      // The leaf's 8 x 8 columns of thresholds along z, each 8 consecutive floats of columns_.
      ThresholdColumns column;
      const std::array<int, 8> i = cells(origin.x(), 0), j = cells(origin.y(), 1);
      const int k = cells(origin.z(), 2)[0];
      for (int x = 0; x < 8; ++x)
        for (int y = 0; y < 8; ++y) column[x][y] = columns_.data() + columnStart(i[x], j[y]) + k;
      return [column](const float* values, unsigned words, detail::LeafWords& bits) { blueNoiseLeafBits(column, values, words, bits); };
    };
  }

private:
  // The mask's cell indices along `axis` for voxel indices v .. v + 7 (tiled, shifted by the offset).
  std::array<int, 8> cells(int v, int axis) const {
    const std::int64_t n = mask_->size()[axis];
    int c = static_cast<int>(((static_cast<std::int64_t>(v) + offset_[axis]) % n + n) % n);
    std::array<int, 8> out;
    for (int d = 0; d < 8; ++d, c = c + 1 == n ? 0 : c + 1) out[d] = c;
    return out;
  }
  std::size_t columnStart(int i, int j) const {
    return (static_cast<std::size_t>(j) * mask_->size()[0] + i) * (mask_->size()[2] + 7);
  }
  // The thresholds rearranged z-fastest, each (i, j) column extended by its first 7 values again, so a
  // leaf's 8 layers are 8 consecutive floats from any start (the mask's own order puts them a plane
  // apart: 8 cache lines a column).
  void buildColumns() {
    const std::array<int, 3>& size = mask_->size();
    columns_.resize(static_cast<std::size_t>(size[0]) * size[1] * (size[2] + 7));
    for (int j = 0; j < size[1]; ++j)
      for (int i = 0; i < size[0]; ++i)
        for (int k = 0; k < size[2] + 7; ++k)
          columns_[columnStart(i, j) + k] = mask_->thresholds()[mask_->index(i, j, k % size[2])];
  }

  std::shared_ptr<const BlueNoiseMask> mask_;
  std::array<int, 3> offset_{};
  std::vector<float> columns_;
};

}  // namespace

openvdb::BoolGrid::Ptr Ditherer::ditherLayers(const openvdb::FloatGrid& fraction, int k0, int k1) {
  if (k0 > k1)
    throw std::invalid_argument("dither: band of layers [" + std::to_string(k0) + ", " + std::to_string(k1) +
                                ") is reversed, expected k0 <= k1");
  if (!fraction.tree().hasActiveTiles()) return ditherLeafVoxels(fraction, k0, k1);
  const openvdb::FloatGrid::Ptr voxels = fraction.deepCopy();
  voxels->tree().voxelizeActiveTiles();
  return ditherLeafVoxels(*voxels, k0, k1);
}

openvdb::BoolGrid::Ptr Ditherer::mapAndDitherLayers(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                                    MappingStats& stats) {
  if (k0 > k1)
    throw std::invalid_argument("dither: band of layers [" + std::to_string(k0) + ", " + std::to_string(k1) +
                                ") is reversed, expected k0 <= k1");
  if (!modulus.tree().hasActiveTiles()) return mapAndDitherLeafVoxels(modulus, map, k0, k1, stats);
  const openvdb::FloatGrid::Ptr voxels = modulus.deepCopy();
  voxels->tree().voxelizeActiveTiles();
  return mapAndDitherLeafVoxels(*voxels, map, k0, k1, stats);
}

openvdb::BoolGrid::Ptr Ditherer::mapAndDitherLeafVoxels(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                                        MappingStats& stats) {
  // A recycler of this call's, not one kept from band to band: no slicer comes here (sliceDesign calls
  // mapAndDitherLayers only for a ditherer that maps as it dithers, which overrides this, and maps the
  // bands for the others into its own recycled fraction trees), so only tests and benchmarks would gain,
  // and a recycler kept by the ditherer would hold fraction trees between calls that keptTrees() (the
  // output trees) and the slicer's estimate do not count. It keeps none: the grid dies with the call.
  voxel::TreeRecycler<openvdb::FloatTree> fresh(0.0f, 0);
  MappingStats band;
  const openvdb::FloatGrid::Ptr fraction = mapBandToFractions(modulus, map, k0, k1, readsNextLayer(), band, fresh);
  openvdb::BoolGrid::Ptr material = ditherLeafVoxels(*fraction, k0, k1);
  stats.voxels += band.voxels;
  stats.clamps += band.clamps;
  return material;
}

openvdb::BoolGrid::Ptr Ditherer::dither(const openvdb::FloatGrid& fraction) {
  reset();
  const openvdb::CoordBBox box = fraction.evalActiveVoxelBoundingBox();
  if (box.empty()) return ditherLayers(fraction, 0, 0);
  return ditherLayers(fraction, box.min().z(), box.max().z() + 1);
}

const std::vector<std::string>& ditherMethodNames() {
  static const std::vector<std::string> names{"white", "blue", "error-diffusion"};
  return names;
}

bool isDitherMethod(const std::string& name) {
  const std::vector<std::string>& names = ditherMethodNames();
  return std::find(names.begin(), names.end(), canonicalDitherName(name)) != names.end();
}

std::string ditherMethodList() {
  return boost::algorithm::join(ditherMethodNames(), ", ");
}

std::string canonicalDitherName(const std::string& name) {
  if (name == "random" || name == "white-noise") return "white";
  if (name == "blue-noise") return "blue";
  return name;
}

std::unique_ptr<Ditherer> makeDitherer(std::string_view method, const DitherOptions& options) {
  if (method == "white") return std::make_unique<WhiteNoiseDitherer>(options.seed, options.checkInterrupt);
  if (method == "blue")
    return std::make_unique<BlueNoiseDitherer>(options.mask ? options.mask : BlueNoiseMask::bundled(), options.seed, options.checkInterrupt);
  if (method == "error-diffusion") return std::make_unique<ErrorDiffusionDitherer>(options.seed, options.checkInterrupt);
  throw std::invalid_argument("unknown ditherer '" + std::string(method) + "', expected one of: " + ditherMethodList());
}

}  // namespace rodfab::materials
