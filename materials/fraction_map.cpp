// The mapping's four-lane vectors pass between functions of this file only; GCC's note that their
// by-value ABI differs without AVX concerns no interface anyone links to.
#pragma GCC diagnostic ignored "-Wpsabi"

#include "materials/fraction_map.hpp"

#include "materials/band_leaves.hpp"
#include "materials/ditherer.hpp"
#include "voxel/tree_assembly.hpp"

#include <immintrin.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
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

// Four lanes (GCC vector extensions; one AVX register in mapWord's AVX2 version, two SSE2 ones
// otherwise): lane by lane the same IEEE operations as the scalar expressions.
typedef double Double4 __attribute__((vector_size(32)));
typedef float Float4 __attribute__((vector_size(16)));
typedef std::int32_t Int4 __attribute__((vector_size(16)));
typedef std::uint32_t UInt4 __attribute__((vector_size(16)));

// The start and rise of the table's intervals of four lanes: the same doubles either way. Scalar loads
// (the baseline), or two AVX2 gathers (called, inlined, from mapWord's AVX2 version only).
struct LoadSegments {
  template <typename Segment>
  [[gnu::always_inline]] static void load(const Segment* segments, Int4 interval, Double4& start, Double4& rise) {
    for (int l = 0; l < 4; ++l) {
      const Segment& s = segments[interval[l]];
      start[l] = s.start;
      rise[l] = s.rise;
    }
  }
};
struct GatherSegments {
  template <typename Segment>
  [[gnu::target("avx2")]] static void load(const Segment* segments, Int4 interval, Double4& start, Double4& rise) {
    static_assert(sizeof(Segment) == 2 * sizeof(double), "a segment is two doubles: start, rise");
    const __m128i twice = reinterpret_cast<__m128i>(interval + interval);  // in doubles
    // The masked form with every lane on (the unmasked one leaves GCC 12 warning of its undefined source).
    const __m256d all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    start = reinterpret_cast<Double4>(_mm256_mask_i32gather_pd(_mm256_setzero_pd(), &segments->start, twice, all, 8));
    rise = reinterpret_cast<Double4>(_mm256_mask_i32gather_pd(_mm256_setzero_pd(), &segments->rise, twice, all, 8));
  }
};

}  // namespace

// mapWord's body, compiled twice: for the baseline and for AVX2 (chosen at load time, see mapWord).
// AVX2 brings no FMA, so no multiply-add is fused and both give interpolate's bits. Integers in 32
// bits: a positive float's bits are below 2^31, so the interval and the offset in it (interpolate's
// 64-bit expressions) are the same numbers; lanes that are clamped (negative, NaN, out of range)
// compute garbage within the table's bounds, then take the clamp's value.
template <typename Load>
inline FractionMap::WordClamps FractionMap::mapWordWith(const float* moduli, std::uint64_t active,
                                                                             float* fractions) const {
  // The members in locals: the stores through `fractions` (memcpy) could alias them otherwise.
  const Segment* segments = segments_.data();
  const int shift = shift_;
  const double inverseWidth = inverseWidth_;
  const Float4 floor = Float4{} + static_cast<float>(floorMpa_), maximum = Float4{} + static_cast<float>(maxModulusMpa_);
  const Float4 floorFraction = Float4{} + static_cast<float>(floorFraction_), one = Float4{} + 1.0f, zero = Float4{};
  const Double4 lowest = Double4{} + floorFraction_, highest = Double4{} + 1.0;
  const Int4 first = Int4{} + static_cast<std::int32_t>(firstInterval_), last = Int4{} + static_cast<std::int32_t>(lastInterval_);
  const Int4 lane = {0, 1, 2, 3};
  Int4 belowCount = {}, aboveCount = {};  // minus the clamped active voxels, lane by lane
  for (int q = 0; q < 64; q += 4) {
    if (!(active >> q & 0xfu)) {  // the thin parts of a rod leave whole quads inactive
      std::memcpy(fractions + q, &zero, sizeof zero);
      continue;
    }
    Float4 e;
    std::memcpy(&e, moduli + q, sizeof e);
    const UInt4 bits = reinterpret_cast<UInt4>(e);
    Int4 interval = reinterpret_cast<Int4>(bits >> shift) - first;
    interval = interval < 0 ? Int4{} : interval;
    interval = interval > last ? last : interval;
    const Int4 offset = reinterpret_cast<Int4>(bits - (reinterpret_cast<UInt4>(first + interval) << shift));
    const Double4 t = __builtin_convertvector(offset, Double4) * inverseWidth;
    Double4 start, rise;
    Load::load(segments, interval, start, rise);
    Double4 v = start + t * rise;
    v = v < lowest ? lowest : v;  // std::clamp(v, floorFraction_, 1.0)
    v = highest < v ? highest : v;
    Float4 f = __builtin_convertvector(v, Float4);
    const Int4 on = ((Int4{} + static_cast<std::int32_t>(active >> q & 0xfu)) >> lane & 1) == 1;
    const Int4 below = ~(e >= floor) & on, above = (e > maximum) & ~below & on;
    f = below ? floorFraction : above ? one : f;
    f = on ? f : zero;
    std::memcpy(fractions + q, &f, sizeof f);
    belowCount += below;
    aboveCount += above;
  }
  return {static_cast<std::uint64_t>(-(belowCount[0] + belowCount[1] + belowCount[2] + belowCount[3])),
          static_cast<std::uint64_t>(-(aboveCount[0] + aboveCount[1] + aboveCount[2] + aboveCount[3]))};
}

// Everything inlined into it (flatten), so compiled for AVX2.
[[gnu::target("avx2"), gnu::flatten]] FractionMap::WordClamps FractionMap::mapWordAvx2(const float* moduli, std::uint64_t active,
                                                                       float* fractions) const {
  return mapWordWith<GatherSegments>(moduli, active, fractions);
}

FractionMap::WordClamps FractionMap::mapWord(const float* moduli, std::uint64_t active, float* fractions) const {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  return avx2 ? mapWordAvx2(moduli, active, fractions) : mapWordWith<LoadSegments>(moduli, active, fractions);
}

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
  segments_.resize(table_.size() - 1);
  for (std::size_t n = 0; n + 1 < table_.size(); ++n) segments_[n] = {table_[n], table_[n + 1] - table_[n]};

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

namespace {

using detail::FloatLeaf;
// The fractions of leaf `in`'s voxels in `mask`, word by word (FractionMap::mapWord), into `leaf`
// (a spare, origin set; its values and mask are overwritten); counts into `s`.
void mapLeaf(const FloatLeaf& in, const detail::LeafMask& mask, const FractionMap& map, MappingStats& s, FloatLeaf& leaf) {
  leaf.setValueMask(mask);
  const float* moduli = in.buffer().data();
  float* fractions = leaf.buffer().data();
  for (openvdb::Index w = 0; w < detail::LeafMask::WORD_COUNT; ++w) {
    const std::uint64_t active = mask.getWord<std::uint64_t>(w);
    if (!active) {  // inactive voxels hold the background, 0
      std::fill_n(fractions + 64 * w, 64, 0.0f);
      continue;
    }
    const FractionMap::WordClamps clamps = map.mapWord(moduli + 64 * w, active, fractions + 64 * w);
    s.voxels += static_cast<std::uint64_t>(std::popcount(active));
    s.clamps.belowFloor += clamps.belowFloor;
    s.clamps.aboveMax += clamps.aboveMax;
  }
}

}  // namespace

openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                       MappingStats& stats, voxel::TreeRecycler<openvdb::FloatTree>& recycler,
                                       const std::function<void()>& checkInterrupt) {
  if (k0 > k1)
    throw std::invalid_argument("modulus to fraction: band of layers [" + std::to_string(k0) + ", " +
                                std::to_string(k1) + ") is reversed, expected k0 <= k1");
  if (modulus.tree().hasActiveTiles()) {
    const openvdb::FloatGrid::Ptr voxels = modulus.deepCopy();
    voxels->tree().voxelizeActiveTiles();
    return mapToFractions(*voxels, map, k0, k1, stats, recycler, checkInterrupt);
  }
  // The leaves in the tree's order, grouped by parent (the counts are sums, the same in any order).
  const detail::LeafGroups groups = detail::leafGroupsInLayers(modulus.tree(), k0, k1);
  voxel::SpareNodes<openvdb::FloatTree> spares = recycler.takeSpares();
  std::vector<std::unique_ptr<FloatLeaf>> out(groups.leaves.size());
  std::vector<MappingStats> perLeaf(groups.leaves.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, groups.leaves.size()), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t l = r.begin(); l != r.end(); ++l) {
      if (checkInterrupt) checkInterrupt();
      const detail::LeafMask mask = detail::activeInLayers(*groups.leaves[l], k0, k1);
      if (mask.isOff()) continue;
      out[l] = spares.leaf(l, groups.leaves[l]->origin());
      mapLeaf(*groups.leaves[l], mask, map, perLeaf[l], *out[l]);
    }
  });
  for (const MappingStats& s : perLeaf) {
    stats.voxels += s.voxels;
    stats.clamps += s.clamps;
  }
  const auto forEachLeaf = [&](std::size_t p, const auto& visit) {
    for (std::size_t l = groups.begin[p]; l != groups.begin[p + 1]; ++l) visit(out[l]);
  };
  auto grid = openvdb::FloatGrid::create(recycler.assemble(groups.parentCount(), forEachLeaf, spares));
  grid->setTransform(modulus.transform().copy());
  grid->setName(kFractionGridName);
  return grid;
}

openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                       MappingStats& stats, const std::function<void()>& checkInterrupt) {
  voxel::TreeRecycler<openvdb::FloatTree> fresh(0.0f);  // nothing to reuse; the tree is deleted when let go
  return mapToFractions(modulus, map, k0, k1, stats, fresh, checkInterrupt);
}

openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, MappingStats& stats) {
  const openvdb::CoordBBox box = modulus.evalActiveVoxelBoundingBox();
  if (box.empty()) return mapToFractions(modulus, map, 0, 0, stats);
  return mapToFractions(modulus, map, box.min().z(), box.max().z() + 1, stats);
}

}  // namespace rodfab::materials
