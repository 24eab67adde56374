#include "materials/ditherer.hpp"

#include "materials/band_leaves.hpp"
#include "materials/counter_hash.hpp"
#include "materials/error_diffusion.hpp"

#include <array>
#include <stdexcept>

namespace rodfab::materials {

namespace {

// Mezzotint as in the published pipeline: Vero where a uniform number drawn for the voxel is below its
// fraction. The number is a hash of (seed, i, j, k), never a sequential stream.
class WhiteNoiseDitherer final : public Ditherer {
public:
  explicit WhiteNoiseDitherer(std::uint64_t seed) : seed_(seed) {}
  std::string_view name() const override { return "white"; }

protected:
  openvdb::BoolGrid::Ptr ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) override {
    const std::uint64_t seed = seed_;
    return detail::ditherPointwise(fraction, k0, k1, [seed](const openvdb::Coord& origin) {
      return [seed, origin](openvdb::Index n, float f) {
        const openvdb::Coord ijk = origin + openvdb::Coord(n >> 6, (n >> 3) & 7, n & 7);
        return voxelUniform(seed, ijk.x(), ijk.y(), ijk.z()) < f;
      };
    });
  }

private:
  std::uint64_t seed_;
};

// Ordered dithering with a tiled blue-noise threshold mask; the seed picks where the tiling starts.
class BlueNoiseDitherer final : public Ditherer {
public:
  BlueNoiseDitherer(std::shared_ptr<const BlueNoiseMask> mask, std::uint64_t seed) : mask_(std::move(mask)) {
    const auto r = philox(seed, 0, 0, 0, HashStream::MaskOffset);
    for (int a = 0; a < 3; ++a) offset_[a] = static_cast<int>(r[a] % static_cast<std::uint32_t>(mask_->size()[a]));
  }
  std::string_view name() const override { return "blue"; }

protected:
  openvdb::BoolGrid::Ptr ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) override {
    const BlueNoiseMask& mask = *mask_;
    const std::array<int, 3> size = mask.size();
    const std::array<int, 3> offset = offset_;
    const float* thresholds = mask.thresholds().data();
    return detail::ditherPointwise(fraction, k0, k1, [&](const openvdb::Coord& origin) {
      // Per leaf: the tile cell's index split into x, y and z parts for the leaf's 8 x 8 x 8 voxels.
      std::array<std::array<std::size_t, 8>, 3> part{};
      const std::array<std::size_t, 3> stride{1, static_cast<std::size_t>(size[0]),
                                              static_cast<std::size_t>(size[0]) * size[1]};
      for (int a = 0; a < 3; ++a)
        for (int d = 0; d < 8; ++d) {
          const std::int64_t v = static_cast<std::int64_t>(origin[a]) + d + offset[a];
          const std::int64_t wrapped = ((v % size[a]) + size[a]) % size[a];
          part[a][d] = static_cast<std::size_t>(wrapped) * stride[a];
        }
      return [part, thresholds](openvdb::Index n, float f) {
        return f > thresholds[part[0][n >> 6] + part[1][(n >> 3) & 7] + part[2][n & 7]];
      };
    });
  }

private:
  std::shared_ptr<const BlueNoiseMask> mask_;
  std::array<int, 3> offset_{};
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

std::string canonicalDitherName(const std::string& name) {
  if (name == "random" || name == "white-noise") return "white";
  if (name == "blue-noise") return "blue";
  return name;
}

std::unique_ptr<Ditherer> makeDitherer(std::string_view method, const DitherOptions& options) {
  if (method == "white") return std::make_unique<WhiteNoiseDitherer>(options.seed);
  if (method == "blue") return std::make_unique<BlueNoiseDitherer>(options.mask ? options.mask : BlueNoiseMask::bundled(), options.seed);
  if (method == "error-diffusion") return std::make_unique<ErrorDiffusionDitherer>(options.seed, options.checkInterrupt);
  std::string valid;
  for (const std::string& n : ditherMethodNames()) valid += (valid.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown ditherer '" + std::string(method) + "', expected one of: " + valid);
}

}  // namespace rodfab::materials
