// The mapping's lane vectors pass between functions of this file only; GCC's note that their
// by-value ABI differs without AVX concerns no interface anyone links to.
#pragma GCC diagnostic ignored "-Wpsabi"

#include "materials/fraction_map.hpp"

#include "materials/band_leaves.hpp"
#include "materials/ditherer.hpp"
#include "voxel/tree_assembly.hpp"

#include <immintrin.h>

#include <algorithm>
#include <array>
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

// N lanes (GCC vector extensions): four in the baseline (two SSE2 registers of doubles), eight in
// mapWord's AVX2 version (one AVX register of floats, two of doubles). Lane by lane the same IEEE
// operations as the scalar expressions, whatever N.
template <int N>
struct Lanes {
  typedef double Double __attribute__((vector_size(8 * N)));
  typedef float Float __attribute__((vector_size(4 * N)));
  typedef std::int32_t Int __attribute__((vector_size(4 * N)));
  typedef std::uint32_t UInt __attribute__((vector_size(4 * N)));
};
using Double4 = Lanes<4>::Double;
using Int4 = Lanes<4>::Int;

// interpolate's start + t rise, clamped to [lowest, highest] (std::clamp(v, floorFraction_, 1.0)), as
// floats: four lanes.
[[gnu::always_inline]] inline Lanes<4>::Float clampedFraction(Double4 start, Double4 rise, Double4 t, Double4 lowest,
                                                              Double4 highest) {
  Double4 v = start + t * rise;
  v = v < lowest ? lowest : v;
  v = highest < v ? highest : v;
  return __builtin_convertvector(v, Lanes<4>::Float);
}

#if RODFAB_TARGET_PATHS
// The same for eight lanes: eight doubles are two AVX registers, which GCC would clamp lane by lane, so
// four at a time.
[[gnu::always_inline]] inline Lanes<8>::Float clampedFraction(Lanes<8>::Double start, Lanes<8>::Double rise, Lanes<8>::Double t,
                                                              Double4 lowest, Double4 highest) {
  const Lanes<4>::Float low = clampedFraction(__builtin_shufflevector(start, start, 0, 1, 2, 3), __builtin_shufflevector(rise, rise, 0, 1, 2, 3),
                                              __builtin_shufflevector(t, t, 0, 1, 2, 3), lowest, highest);
  const Lanes<4>::Float high = clampedFraction(__builtin_shufflevector(start, start, 4, 5, 6, 7), __builtin_shufflevector(rise, rise, 4, 5, 6, 7),
                                               __builtin_shufflevector(t, t, 4, 5, 6, 7), lowest, highest);
  return __builtin_shufflevector(low, high, 0, 1, 2, 3, 4, 5, 6, 7);
}
#endif

// The lanes of group q (voxels q .. q + N - 1 of a word) whose bit is set in `active`: all ones, else 0.
template <int N>
[[gnu::always_inline]] inline typename Lanes<N>::Int onLanes(std::uint64_t active, int q) {
  using Int = typename Lanes<N>::Int;
  Int lane;
  for (int l = 0; l < N; ++l) lane[l] = l;
  return ((Int{} + static_cast<std::int32_t>(active >> q & ((std::uint64_t(1) << N) - 1))) >> lane & 1) == 1;
}

// Whether the active voxels of a word (`active` not 0) all hold the modulus `value`, bit for bit.
template <int N>
[[gnu::always_inline]] inline bool allActiveAre(const float* moduli, std::uint64_t active, std::uint32_t value) {
  using UInt = typename Lanes<N>::UInt;
  UInt differ = {};
  for (int q = 0; q < 64; q += N) {
    UInt bits;
    std::memcpy(&bits, moduli + q, sizeof bits);
    differ |= (bits ^ value) & reinterpret_cast<UInt>(onLanes<N>(active, q));
  }
  bool none = true;
  for (int l = 0; l < N; ++l) none &= differ[l] == 0;
  return none;
}

// The voxels counted down lane by lane (-1 each, at most 2^23 a lane): how many.
template <int N>
[[gnu::always_inline]] inline std::uint64_t countedDown(typename Lanes<N>::Int lanes) {
  std::int64_t sum = 0;
  for (int l = 0; l < N; ++l) sum -= lanes[l];
  return static_cast<std::uint64_t>(sum);
}

// The start and rise of the table's intervals of the lanes: the same doubles either way. Scalar loads
// of four lanes (the baseline), or four AVX2 gathers of eight (called, inlined, from mapWord's AVX2
// version only).
struct LoadSegments {
  static constexpr int kLanes = 4;
  template <typename Segment>
  [[gnu::always_inline]] static void load(const Segment* segments, Int4 interval, Double4& start, Double4& rise) {
    for (int l = 0; l < 4; ++l) {
      const Segment& s = segments[interval[l]];
      start[l] = s.start;
      rise[l] = s.rise;
    }
  }
};
#if RODFAB_TARGET_PATHS
struct GatherSegments {
  static constexpr int kLanes = 8;
  template <typename Segment>
  [[gnu::target("avx2")]] static void load(const Segment* segments, Lanes<8>::Int interval, Lanes<8>::Double& start,
                                           Lanes<8>::Double& rise) {
    static_assert(sizeof(Segment) == 2 * sizeof(double), "a segment is two doubles: start, rise");
    const Lanes<8>::Int twice = interval + interval;  // in doubles
    const __m128i low = reinterpret_cast<__m128i>(__builtin_shufflevector(twice, twice, 0, 1, 2, 3));
    const __m128i high = reinterpret_cast<__m128i>(__builtin_shufflevector(twice, twice, 4, 5, 6, 7));
    // The masked form with every lane on (the unmasked one leaves GCC 12 warning of its undefined source).
    const __m256d all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    const __m256d none = _mm256_setzero_pd();
    const Double4 startLow = reinterpret_cast<Double4>(_mm256_mask_i32gather_pd(none, &segments->start, low, all, 8));
    const Double4 startHigh = reinterpret_cast<Double4>(_mm256_mask_i32gather_pd(none, &segments->start, high, all, 8));
    const Double4 riseLow = reinterpret_cast<Double4>(_mm256_mask_i32gather_pd(none, &segments->rise, low, all, 8));
    const Double4 riseHigh = reinterpret_cast<Double4>(_mm256_mask_i32gather_pd(none, &segments->rise, high, all, 8));
    start = __builtin_shufflevector(startLow, startHigh, 0, 1, 2, 3, 4, 5, 6, 7);
    rise = __builtin_shufflevector(riseLow, riseHigh, 0, 1, 2, 3, 4, 5, 6, 7);
  }
};
#endif

}  // namespace

// mapWords' body, compiled twice: for the baseline (four lanes) and for AVX2 (eight; chosen at load
// time, see mapWords). AVX2 brings no FMA, so no multiply-add is fused and both give interpolate's
// bits. Integers in 32 bits: a positive float's bits are below 2^31, so the interval and the offset in
// it (interpolate's 64-bit expressions) are the same numbers; lanes that are clamped (negative, NaN,
// out of range) compute garbage within the table's bounds, then take the clamp's value.
template <typename Load>
inline FractionMap::WordClamps FractionMap::mapWordsWith(const float* moduli, const std::uint64_t* activeWords, std::size_t words,
                                                         float* fractions) const {
  constexpr int N = Load::kLanes;
  using Double = typename Lanes<N>::Double;
  using Float = typename Lanes<N>::Float;
  using Int = typename Lanes<N>::Int;
  using UInt = typename Lanes<N>::UInt;
  constexpr std::uint64_t kLaneBits = (std::uint64_t(1) << N) - 1;
  // The members in locals: the stores through `fractions` (memcpy) could alias them otherwise.
  const Segment* segments = segments_.data();
  const int shift = shift_;
  const double inverseWidth = inverseWidth_;
  const Float floor = Float{} + static_cast<float>(floorMpa_), maximum = Float{} + static_cast<float>(maxModulusMpa_);
  const Float floorFraction = Float{} + static_cast<float>(floorFraction_), one = Float{} + 1.0f, zero = Float{};
  const Double4 lowest = Double4{} + floorFraction_, highest = Double4{} + 1.0;
  const Int first = Int{} + static_cast<std::int32_t>(firstInterval_), last = Int{} + static_cast<std::int32_t>(lastInterval_);
  // N lanes' fractions of the moduli `e`, every lane computed, the clamps applied (flags in `below`
  // and `above`: all ones where clamped).
  const auto laneFractions = [&](Float e, Int& below, Int& above) {
    const UInt bits = reinterpret_cast<UInt>(e);
    Int interval = reinterpret_cast<Int>(bits >> shift) - first;
    interval = interval < 0 ? Int{} : interval;
    interval = interval > last ? last : interval;
    const Int offset = reinterpret_cast<Int>(bits - (reinterpret_cast<UInt>(first + interval) << shift));
    const Double t = __builtin_convertvector(offset, Double) * inverseWidth;
    Double start, rise;
    Load::load(segments, interval, start, rise);
    const Float f = clampedFraction(start, rise, t, lowest, highest);
    below = ~(e >= floor);
    above = (e > maximum) & ~below;
    return below ? floorFraction : above ? one : f;
  };
  std::uint64_t belowTotal = 0, aboveTotal = 0;  // the uniform words' clamped voxels
  Int belowCount = {}, aboveCount = {};           // minus the other words' clamped voxels, lane by lane (at most 512)
  for (std::size_t w = 0; w < words; ++w, moduli += 64, fractions += 64) {
    const std::uint64_t active = activeWords[w];
    if (!active) {  // inactive voxels hold the background, 0
      std::fill_n(fractions, 64, 0.0f);
      continue;
    }
    if (const std::uint64_t voxels = static_cast<std::uint64_t>(std::popcount(active)); voxels > 1) {
      // A word whose active voxels all hold the same modulus, bit for bit (two thirds of the lattice
      // class's voxels, where E depends on z only; every word of the dense block), maps it once: the
      // same lanes' arithmetic on that value, so the same fraction, stored into every active voxel.
      // (The last active voxel first: where E varies along the rod, it differs, and the word is not read twice.)
      const std::uint32_t value = std::bit_cast<std::uint32_t>(moduli[std::countr_zero(active)]);
      if (std::bit_cast<std::uint32_t>(moduli[63 - std::countl_zero(active)]) == value && allActiveAre<N>(moduli, active, value)) {
        Int below, above;
        const Float f = laneFractions(reinterpret_cast<Float>(UInt{} + value), below, above);  // every lane alike, -0 and NaN kept
        for (int q = 0; q < 64; q += N) {
          const Float out = onLanes<N>(active, q) ? f : zero;
          std::memcpy(fractions + q, &out, sizeof out);
        }
        belowTotal += below[0] ? voxels : 0;
        aboveTotal += above[0] ? voxels : 0;
        continue;
      }
    }
    for (int q = 0; q < 64; q += N) {
      if (!(active >> q & kLaneBits)) {  // the thin parts of a rod leave whole groups inactive
        std::memcpy(fractions + q, &zero, sizeof zero);
        continue;
      }
      Float e;
      std::memcpy(&e, moduli + q, sizeof e);
      Int below, above;
      Float f = laneFractions(e, below, above);
      if ((active >> q & kLaneBits) != kLaneBits) {  // the inactive lanes' values and flags left out
        const Int on = onLanes<N>(active, q);
        f = on ? f : zero;
        below &= on;
        above &= on;
      }
      std::memcpy(fractions + q, &f, sizeof f);
      belowCount += below;
      aboveCount += above;
    }
  }
  return {belowTotal + countedDown<N>(belowCount), aboveTotal + countedDown<N>(aboveCount)};
}

#if RODFAB_TARGET_PATHS
// Everything inlined into it (flatten), so compiled for AVX2.
[[gnu::target("avx2"), gnu::flatten]] FractionMap::WordClamps FractionMap::mapWordsAvx2(const float* moduli, const std::uint64_t* active,
                                                                                        std::size_t words, float* fractions) const {
  return mapWordsWith<GatherSegments>(moduli, active, words, fractions);
}
#endif

FractionMap::WordClamps FractionMap::mapWords(const float* moduli, const std::uint64_t* active, std::size_t words, float* fractions) const {
  // mapWordsWith counts the clamps lane by lane in 32 bits: at most 2^20 words (2^23 voxels a lane) a call.
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  WordClamps total;
  for (std::size_t w = 0; w < words; w += kChunk) {
    const std::size_t n = std::min(kChunk, words - w);
#if RODFAB_TARGET_PATHS
    static const bool avx2 = __builtin_cpu_supports("avx2");
    const WordClamps c = avx2 ? mapWordsAvx2(moduli + 64 * w, active + w, n, fractions + 64 * w)
                              : mapWordsWith<LoadSegments>(moduli + 64 * w, active + w, n, fractions + 64 * w);
#else
    const WordClamps c = mapWordsWith<LoadSegments>(moduli + 64 * w, active + w, n, fractions + 64 * w);
#endif
    total.belowFloor += c.belowFloor;
    total.aboveMax += c.aboveMax;
  }
  return total;
}

FractionMap::WordClamps FractionMap::mapWord(const float* moduli, std::uint64_t active, float* fractions) const {
  return mapWords(moduli, &active, 1, fractions);
}

FractionMap::FractionMap(const calibration::Calibration& calibration, std::size_t nodes)
    : floorMpa_(calibration.floorMpa()), floorFraction_(calibration.floorFraction()), maxModulusMpa_(calibration.maxModulusMpa()) {
  if (nodes < 2) throw std::invalid_argument("fraction map: need at least 2 nodes, got " + std::to_string(nodes));
  if (!(floorMpa_ > double(std::numeric_limits<float>::min()) && maxModulusMpa_ > floorMpa_ &&
        maxModulusMpa_ < double(std::numeric_limits<float>::max())))
    throw std::invalid_argument("fraction map: the calibration's floor and maximum modulus must satisfy 0 < floor < max "
                                "within the float range, got " + std::to_string(floorMpa_) + " and " + std::to_string(maxModulusMpa_));
  // Every value the map gives lies in [floor fraction, 1]: the fused ditherers check no fraction.
  if (!(floorFraction_ >= 0.0 && floorFraction_ < 1.0))
    throw std::invalid_argument("fraction map: the calibration's floor fraction must lie in [0, 1), got " + std::to_string(floorFraction_));
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
// (a spare, origin set; its values and mask are overwritten); counts the voxels of `counted` (a part
// of `mask`) into `s`.
void mapLeaf(const FloatLeaf& in, const detail::LeafMask& mask, const detail::LeafMask& counted, const FractionMap& map,
             MappingStats& s, FloatLeaf& leaf) {
  leaf.setValueMask(mask);
  const std::array<std::uint64_t, 8> active = detail::maskWords(mask);
  FractionMap::WordClamps clamps = map.mapWords(in.buffer().data(), active.data(), active.size(), leaf.buffer().data());
  if (counted != mask) {  // voxels of the uncounted layer too: the counted ones' clamps apart
    alignas(64) std::array<float, FloatLeaf::SIZE> scratch;
    const std::array<std::uint64_t, 8> countedWords = detail::maskWords(counted);
    clamps = map.mapWords(in.buffer().data(), countedWords.data(), countedWords.size(), scratch.data());
  }
  s.voxels += counted.countOn();
  s.clamps.belowFloor += clamps.belowFloor;
  s.clamps.aboveMax += clamps.aboveMax;
}

// mapToFractions over layers [k0, k1), the stats counting layers [k0, countEnd) only (countEnd <= k1).
openvdb::FloatGrid::Ptr mapLayers(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1, int countEnd,
                                  MappingStats& stats, voxel::TreeRecycler<openvdb::FloatTree>& recycler,
                                  const std::function<void()>& checkInterrupt) {
  if (k0 > k1)
    throw std::invalid_argument("modulus to fraction: band of layers [" + std::to_string(k0) + ", " +
                                std::to_string(k1) + ") is reversed, expected k0 <= k1");
  if (modulus.tree().hasActiveTiles()) {
    const openvdb::FloatGrid::Ptr voxels = modulus.deepCopy();
    voxels->tree().voxelizeActiveTiles();
    return mapLayers(*voxels, map, k0, k1, countEnd, stats, recycler, checkInterrupt);
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
      const detail::LeafMask counted = countEnd >= k1 ? mask : detail::activeInLayers(*groups.leaves[l], k0, countEnd);
      mapLeaf(*groups.leaves[l], mask, counted, map, perLeaf[l], *out[l]);
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

}  // namespace

openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                       MappingStats& stats, voxel::TreeRecycler<openvdb::FloatTree>& recycler,
                                       const std::function<void()>& checkInterrupt) {
  return mapLayers(modulus, map, k0, k1, k1, stats, recycler, checkInterrupt);
}

openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                       MappingStats& stats, const std::function<void()>& checkInterrupt) {
  voxel::TreeRecycler<openvdb::FloatTree> fresh(0.0f);  // nothing to reuse; the tree is deleted when let go
  return mapToFractions(modulus, map, k0, k1, stats, fresh, checkInterrupt);
}

openvdb::FloatGrid::Ptr mapBandToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                           bool withNextLayer, MappingStats& stats,
                                           voxel::TreeRecycler<openvdb::FloatTree>& recycler,
                                           const std::function<void()>& checkInterrupt) {
  // Layer k1 mapped with the band, into the same tree from the same spares: mapped apart into fresh
  // leaves and merged (Tree::merge, which resets each stolen leaf's background voxel by voxel), it was
  // a third of error diffusion's "voxelize + map" on the lattice (bench/README.md).
  return mapLayers(modulus, map, k0, withNextLayer ? k1 + 1 : k1, k1, stats, recycler, checkInterrupt);
}

openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, MappingStats& stats) {
  const openvdb::CoordBBox box = modulus.evalActiveVoxelBoundingBox();
  if (box.empty()) return mapToFractions(modulus, map, 0, 0, stats);
  return mapToFractions(modulus, map, box.min().z(), box.max().z() + 1, stats);
}

}  // namespace rodfab::materials
