#include "materials/fraction_map.hpp"

#include "materials/band_leaves.hpp"
#include "materials/ditherer.hpp"

#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rodfab::materials {

namespace {

// The largest float <= x (down) or the smallest float >= x (up), for positive finite x.
float floatBeside(double x, bool up) {
  float f = static_cast<float>(x);
  if (up ? double(f) < x : double(f) > x) f = std::nextafter(f, up ? std::numeric_limits<float>::infinity() : 0.0f);
  return f;
}

// The line through (x0, y0) and (x1, y1) at x; y1 where the points coincide.
double lineAt(double x0, double y0, double x1, double y1, double x) {
  return x1 > x0 ? y0 + (x - x0) * (y1 - y0) / (x1 - x0) : y1;
}

}  // namespace

FractionMap::FractionMap(const calibration::Calibration& calibration, std::size_t nodes)
    : floorMpa_(calibration.floorMpa()), floorFraction_(calibration.floorFraction()), maxModulusMpa_(calibration.maxModulusMpa()) {
  if (nodes < 2) throw std::invalid_argument("fraction map: need at least 2 nodes, got " + std::to_string(nodes));
  if (!(floorMpa_ > double(std::numeric_limits<float>::min()) && maxModulusMpa_ > floorMpa_ &&
        maxModulusMpa_ < double(std::numeric_limits<float>::max())))
    throw std::invalid_argument("fraction map: the calibration's floor and maximum modulus must satisfy 0 < floor < max "
                                "within the float range, got " + std::to_string(floorMpa_) + " and " + std::to_string(maxModulusMpa_));
  // Intervals per octave: the power of two that puts at least `nodes` nodes between floor and max.
  const double octaves = std::log2(maxModulusMpa_ / floorMpa_);
  const double perOctave = std::max(1.0, static_cast<double>(nodes - 1) / octaves);
  const int mantissaBits = std::clamp(static_cast<int>(std::ceil(std::log2(perOctave) - 1e-12)), 0, 20);
  shift_ = 23 - mantissaBits;
  inverseWidth_ = std::ldexp(1.0, -shift_);
  const auto bitsOf = [](float f) { return static_cast<std::int64_t>(std::bit_cast<std::uint32_t>(f)); };
  firstInterval_ = bitsOf(floatBeside(floorMpa_, false)) >> shift_;
  lastInterval_ = (bitsOf(floatBeside(maxModulusMpa_, true)) >> shift_) - firstInterval_;
  const auto node = [&](std::int64_t n) {
    return double(std::bit_cast<float>(static_cast<std::uint32_t>((firstInterval_ + n) << shift_)));
  };
  const auto exact = [&](double e) { return calibration.fraction(e).fraction; };

  // Inner nodes exactly (above the floor by construction; at or past the maximum, 1); the outer two
  // on the lines through the exact values at the floor and the maximum.
  const std::int64_t L = lastInterval_;
  table_.assign(static_cast<std::size_t>(L + 2), 0.0);
  for (std::int64_t n = 1; n <= L; ++n) table_[std::size_t(n)] = node(n) >= maxModulusMpa_ ? 1.0 : exact(node(n));
  if (L >= 1 && node(1) < maxModulusMpa_) table_[0] = lineAt(floorMpa_, floorFraction_, node(1), table_[1], node(0));
  else table_[0] = lineAt(floorMpa_, floorFraction_, maxModulusMpa_, 1.0, node(0));
  const bool innerLeft = L >= 1 && node(L) > floorMpa_;
  const double x0 = innerLeft ? node(L) : floorMpa_, y0 = innerLeft ? table_[std::size_t(L)] : floorFraction_;
  table_[std::size_t(L + 1)] = x0 >= maxModulusMpa_ ? 1.0 : lineAt(x0, y0, maxModulusMpa_, 1.0, node(L + 1));
  // The inverse is solved to 1e-9; keep the table monotone regardless.
  for (std::size_t n = 1; n < table_.size(); ++n) table_[n] = std::max(table_[n], table_[n - 1]);

  // Midpoint errors of every interval (cut to [floor, max]) as the lookup computes them.
  double worst = 0.0;
  for (std::int64_t n = 0; n <= L; ++n) {
    const double lo = std::max(node(n), floorMpa_), hi = std::min(node(n + 1), maxModulusMpa_);
    if (!(lo < hi)) continue;
    const float mid = static_cast<float>(0.5 * (lo + hi));
    if (!(mid >= floorMpa_ && mid <= maxModulusMpa_)) continue;
    worst = std::max(worst, std::abs(interpolate(mid) - exact(mid)));
  }
  // Plus the result's rounding to float and the modulus's rounding to float (relative 6e-8 of E).
  errorBound_ = 2.0 * worst + std::ldexp(1.0, -23);
}

openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                       MappingStats& stats, const std::function<void()>& checkInterrupt) {
  if (k0 > k1)
    throw std::invalid_argument("modulus to fraction: band of layers [" + std::to_string(k0) + ", " +
                                std::to_string(k1) + ") is reversed, expected k0 <= k1");
  if (modulus.tree().hasActiveTiles()) {
    const openvdb::FloatGrid::Ptr voxels = modulus.deepCopy();
    voxels->tree().voxelizeActiveTiles();
    return mapToFractions(*voxels, map, k0, k1, stats, checkInterrupt);
  }
  using detail::FloatLeaf;
  const std::vector<const FloatLeaf*> leaves = detail::leavesInLayers(modulus.tree(), k0, k1);
  std::vector<std::unique_ptr<FloatLeaf>> out(leaves.size());
  std::vector<MappingStats> perLeaf(leaves.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves.size()), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t l = r.begin(); l != r.end(); ++l) {
      if (checkInterrupt) checkInterrupt();
      const FloatLeaf& in = *leaves[l];
      const detail::LeafMask mask = detail::activeInLayers(in, k0, k1);
      if (mask.isOff()) continue;
      auto leaf = std::make_unique<FloatLeaf>(in.origin(), 0.0f, false);
      leaf->setValueMask(mask);
      const float* moduli = in.buffer().data();
      float* fractions = leaf->buffer().data();
      MappingStats& s = perLeaf[l];
      // Word by word over the active bits; the clamps are rare and counted where they happen.
      // The grid holds E as floats: E = floor (or max) exactly is stored as the float nearest to it,
      // which may lie just beyond; rounding is monotone, so these comparisons are E's own.
      const auto floor = static_cast<float>(map.floorMpa()), maximum = static_cast<float>(map.maxModulusMpa());
      const auto floorFraction = static_cast<float>(map.floorFraction());
      for (openvdb::Index w = 0; w < detail::LeafMask::WORD_COUNT; ++w) {
        std::uint64_t active = mask.getWord<std::uint64_t>(w);
        s.voxels += static_cast<std::uint64_t>(std::popcount(active));
        while (active) {
          const openvdb::Index n = w * 64 + static_cast<openvdb::Index>(std::countr_zero(active));
          active &= active - 1;
          const float e = moduli[n];
          if (!(e >= floor)) {  // also NaN
            fractions[n] = floorFraction;
            s.clamps.count(calibration::Clamp::BelowFloor);
          } else if (e > maximum) {
            fractions[n] = 1.0f;
            s.clamps.count(calibration::Clamp::AboveMax);
          } else {
            fractions[n] = static_cast<float>(map.interpolate(e));
          }
        }
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
