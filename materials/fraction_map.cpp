#include "materials/fraction_map.hpp"

#include "materials/band_leaves.hpp"
#include "materials/ditherer.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rodfab::materials {

FractionMap::FractionMap(const calibration::Calibration& calibration, std::size_t nodes)
    : floorMpa_(calibration.floorMpa()),
      floorFraction_(calibration.floorFraction()),
      maxModulusMpa_(calibration.maxModulusMpa()),
      lnFloor_(std::log(calibration.floorMpa())) {
  if (nodes < 2) throw std::invalid_argument("fraction map: need at least 2 nodes, got " + std::to_string(nodes));
  const double lnMax = std::log(maxModulusMpa_);
  const double step = (lnMax - lnFloor_) / static_cast<double>(nodes - 1);
  inverseStep_ = step > 0 ? 1.0 / step : 0.0;
  const auto exact = [&](double lnE) { return calibration.fraction(std::exp(lnE)).fraction; };
  table_.resize(nodes);
  for (std::size_t n = 0; n < nodes; ++n) {
    // The ends exactly: the floor's fraction and 1 (no exp/log round trip may push them past a clamp).
    const double f = n == 0 ? floorFraction_ : n + 1 == nodes ? 1.0 : exact(lnFloor_ + step * static_cast<double>(n));
    // The inverse is solved to 1e-9; keep the table monotone regardless.
    table_[n] = n == 0 ? f : std::max(f, table_[n - 1]);
  }
  double worst = 0.0;
  for (std::size_t n = 0; n + 1 < nodes; ++n) {
    const double mid = exact(lnFloor_ + step * (static_cast<double>(n) + 0.5));
    worst = std::max(worst, std::abs(0.5 * (table_[n] + table_[n + 1]) - mid));
  }
  errorBound_ = 2.0 * worst + std::ldexp(1.0, -24);
}

openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                       MappingStats& stats) {
  if (k0 > k1)
    throw std::invalid_argument("modulus to fraction: band of layers [" + std::to_string(k0) + ", " +
                                std::to_string(k1) + ") is reversed, expected k0 <= k1");
  if (modulus.tree().hasActiveTiles()) {
    const openvdb::FloatGrid::Ptr voxels = modulus.deepCopy();
    voxels->tree().voxelizeActiveTiles();
    return mapToFractions(*voxels, map, k0, k1, stats);
  }
  using detail::FloatLeaf;
  const std::vector<const FloatLeaf*> leaves = detail::leavesInLayers(modulus.tree(), k0, k1);
  std::vector<std::unique_ptr<FloatLeaf>> out(leaves.size());
  std::vector<MappingStats> perLeaf(leaves.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves.size()), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t l = r.begin(); l != r.end(); ++l) {
      const FloatLeaf& in = *leaves[l];
      const detail::LeafMask mask = detail::activeInLayers(in, k0, k1);
      if (mask.isOff()) continue;
      auto leaf = std::make_unique<FloatLeaf>(in.origin(), 0.0f, false);
      leaf->setValueMask(mask);
      const float* moduli = in.buffer().data();
      float* fractions = leaf->buffer().data();
      MappingStats& s = perLeaf[l];
      for (auto it = mask.beginOn(); it; ++it) {
        const calibration::FractionResult result = map.fraction(moduli[it.pos()]);
        fractions[it.pos()] = static_cast<float>(result.fraction);
        s.clamps.count(result.clamp);
        ++s.voxels;
      }
      out[l] = std::move(leaf);
    }
  });
  auto grid = openvdb::FloatGrid::create(0.0f);
  grid->setTransform(modulus.transform().copy());
  grid->setName(kFractionGridName);
  for (std::size_t l = 0; l < leaves.size(); ++l) {
    stats.voxels += perLeaf[l].voxels;
    stats.clamps += perLeaf[l].clamps;
    if (out[l]) grid->tree().addLeaf(out[l].release());
  }
  return grid;
}

openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, MappingStats& stats) {
  const openvdb::CoordBBox box = modulus.evalActiveVoxelBoundingBox();
  if (box.empty()) return mapToFractions(modulus, map, 0, 0, stats);
  return mapToFractions(modulus, map, box.min().z(), box.max().z() + 1, stats);
}

}  // namespace rodfab::materials
