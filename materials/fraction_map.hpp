// Young's modulus to Vero fraction over a grid, through a calibration, band by band of layers.
//
// Input: openvdb::FloatGrid "modulus_mpa" (active voxels = inside the part, value = E in MPa). Output:
// "vero_fraction" with the same active voxels of the requested layers and the same transform.
#pragma once

#include "calibration/calibration.hpp"
#include "common/cpu_clones.hpp"
#include "voxel/tree_assembly.hpp"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <functional>
#include <vector>

namespace rodfab::materials {

// calibration.fraction(E) tabulated for the billions of voxels of a job, indexed by the bits of E as a
// float: the leading bits of a positive float (exponent and the top `mantissaBits` bits of the
// mantissa) split every octave of E into 2^mantissaBits equal intervals, and within one the remaining
// bits are linear in E. So a voxel costs a shift, a mask and one linear interpolation in E between
// exact values of the inverse, with no logarithm (which cost ~8 ns a voxel, more than the lookup).
// The nodes are floats, exact; the interval holding the floor is cut at the floor and the one holding
// the maximum at the maximum (their outer node is the line through the exact values extrapolated), so
// the table is exact at both ends. Monotone, like the exact inverse. Outside [floor, max] the
// calibration's clamps apply unchanged: below the floor (or NaN) -> the floor's fraction, above the
// maximum -> 1.
//
// Error bound: linear interpolation errs by at most h^2 / 8 * max |f''| on an interval of width h,
// which is where the midpoint error sits. The constructor measures the midpoint error of every
// interval against the exact inverse and states twice the largest, plus the rounding of the result
// to float, as interpolationErrorBound(); with the default (at least 4096 nodes between the floor and
// the maximum, which gives 1024 intervals an octave for the bundled calibration) that is about 1e-6
// in f, below the 1 / 184,320 = 5.4e-6 step of the blue-noise thresholds.
class FractionMap {
public:
  // `nodes`: at least this many table nodes between the floor and the maximum (the intervals per
  // octave are the power of two that gives them, at most 2^20). Throws std::invalid_argument for fewer
  // than 2 nodes, or a calibration whose floor fraction is not in [0, 1) (so every fraction the map
  // gives is in [0, 1]: Ditherer::mapAndDitherLayers checks none).
  explicit FractionMap(const calibration::Calibration& calibration, std::size_t nodes = 4096);

  // Const, thread-safe, allocation-free. The clamps are decided on the double; inside the range E is
  // rounded to float for the lookup (a relative change below 6e-8, within the error bound).
  calibration::FractionResult fraction(double modulusMpa) const {
    if (!(modulusMpa >= floorMpa_)) return {floorFraction_, calibration::Clamp::BelowFloor};  // also NaN
    if (modulusMpa > maxModulusMpa_) return {1.0, calibration::Clamp::AboveMax};
    return {interpolate(static_cast<float>(modulusMpa)), calibration::Clamp::None};
  }
  // The same for a float modulus known to be in [floorMpa(), maxModulusMpa()].
  double interpolate(float modulusMpa) const {
    const std::uint32_t bits = std::bit_cast<std::uint32_t>(modulusMpa);
    // Rounding to float may step just outside [floor, max]: the end intervals extend the line, and the
    // result is clamped to the range of the inverse.
    const std::int64_t interval = std::clamp<std::int64_t>(std::int64_t(bits >> shift_) - firstInterval_, 0, lastInterval_);
    const double t = static_cast<double>(std::int64_t(bits) - ((firstInterval_ + interval) << shift_)) * inverseWidth_;
    const Segment& s = segments_[static_cast<std::size_t>(interval)];
    return std::clamp(s.start + t * s.rise, floorFraction_, 1.0);
  }

  // The fractions of one leaf word (offsets 64 w .. 64 w + 63 of a leaf): fractions[b] for the 64
  // moduli[b] whose bit b of `active` is set, by mapToFractions' rule (the clamps decided on the float:
  // !(E >= float(floor)), NaN too, gives the floor's fraction, E > float(max) gives 1, anything else
  // float(interpolate(E))), and 0 where the bit is clear. Four voxels a step without branches (eight in
  // the AVX2 version), lane by lane the scalar expressions (same bits); a word whose active moduli are
  // one value, bit for bit, is mapped once (the same lanes' arithmetic, so the same bits) and stored into
  // each active voxel. Returns how many active voxels were clamped.
  struct WordClamps {
    std::uint64_t belowFloor = 0, aboveMax = 0;
  };
  WordClamps mapWord(const float* moduli, std::uint64_t active, float* fractions) const;
  // mapWord for `words` consecutive words (a leaf's 8: moduli[64 w ..], active[w], fractions[64 w ..]),
  // a word whose `active` is 0 set to 0; the clamps summed. The same bits as mapWord word by word, with
  // the constants set up once a call, not once a word (the set-up and the flags' reduction were about
  // as much of a word's work as its look-ups: bench/README.md).
  WordClamps mapWords(const float* moduli, const std::uint64_t* active, std::size_t words, float* fractions) const;

  double interpolationErrorBound() const { return errorBound_; }
  double floorMpa() const { return floorMpa_; }
  double floorFraction() const { return floorFraction_; }
  double maxModulusMpa() const { return maxModulusMpa_; }
  std::size_t nodes() const { return table_.size(); }
  int intervalsPerOctaveLog2() const { return 23 - shift_; }

private:
  // mapWords' body for a way of loading the table's segments (fraction_map.cpp), and its AVX2 version
  // (gathers), which mapWords calls where the processor has AVX2.
  template <typename Load>
  WordClamps mapWordsWith(const float* moduli, const std::uint64_t* active, std::size_t words, float* fractions) const;
#if RODFAB_TARGET_PATHS
  [[gnu::target("avx2")]] WordClamps mapWordsAvx2(const float* moduli, const std::uint64_t* active, std::size_t words,
                                                  float* fractions) const;
#endif

  std::vector<double> table_;  // node values; interval n spans float bits [(first + n) << shift, (first + n + 1) << shift)
  // Interval n as interpolate uses it: its first node's value and the rise to the next, table_[n + 1] -
  // table_[n] (computed once; the same double the subtraction gives per voxel).
  struct Segment {
    double start, rise;
  };
  std::vector<Segment> segments_;
  double floorMpa_, floorFraction_, maxModulusMpa_;
  int shift_ = 13;
  std::int64_t firstInterval_ = 0, lastInterval_ = 0;
  double inverseWidth_ = 0.0;  // 2^-shift
  double errorBound_ = 0.0;
};

struct MappingStats {
  std::uint64_t voxels = 0;
  calibration::ClampCounts clamps;  // belowFloor: E < floor (set to the floor's fraction); aboveMax: E > max
};

// Maps the active voxels of layers [k0, k1) (active tiles included); counts clamps per leaf in
// parallel and sums them, so `stats` is the same for any thread count. Throws std::invalid_argument
// for k0 > k1. `checkInterrupt`, when given, is called before each leaf on whichever thread maps it
// (so a band of large layers stops within one leaf's work); what it throws stops the other leaves and
// leaves this function, with `stats` unchanged.
openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                       MappingStats& stats, const std::function<void()>& checkInterrupt = {});
// The same, the output's leaves and internal nodes taken from earlier outputs that came back to
// `recycler` (voxel/tree_assembly.hpp; background 0), and the output's tree returned to it when its
// owners let go: a slicer streaming bands allocates them for the first bands only. Several calls may
// run at once with the same recycler (TreeRecycler is thread-safe; each call takes its own spares), and
// the output's values do not depend on which spare leaves it was built from (every value is set).
openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                       MappingStats& stats, voxel::TreeRecycler<openvdb::FloatTree>& recycler,
                                       const std::function<void()>& checkInterrupt = {});
// A ditherer's band: mapToFractions(modulus, map, k0, k1, stats, recycler, checkInterrupt) and, when
// `withNextLayer` (a ditherer that reads layer k1: Ditherer::readsNextLayer, error diffusion), layer k1
// mapped into the same tree, not counted in `stats` (its voxels are counted with their own band).
// Throws as mapToFractions.
openvdb::FloatGrid::Ptr mapBandToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                           bool withNextLayer, MappingStats& stats,
                                           voxel::TreeRecycler<openvdb::FloatTree>& recycler,
                                           const std::function<void()>& checkInterrupt = {});
// The whole grid.
openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, MappingStats& stats);

}  // namespace rodfab::materials
