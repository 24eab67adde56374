// Young's modulus to Vero fraction over a grid, through a calibration, band by band of layers.
//
// Input: openvdb::FloatGrid "modulus_mpa" (active voxels = inside the part, value = E in MPa). Output:
// "vero_fraction" with the same active voxels of the requested layers and the same transform.
#pragma once

#include "calibration/calibration.hpp"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace rodfab::materials {

// calibration.fraction(E) tabulated in ln E for the billions of voxels of a job: nodes equally spaced
// from ln(floor) to ln(E at 100 % Vero), linear interpolation in between (monotone, like the exact
// inverse). Outside that range the calibration's clamps apply unchanged: below the floor (or NaN) ->
// the floor's fraction, above the maximum -> 1.
//
// Error bound: linear interpolation errs by at most h^2 / 8 * max |d2f / d(ln E)^2| on a node interval
// of width h, which is where the midpoint error sits. The constructor measures the midpoint error of
// every interval against the exact inverse and states twice the largest, plus the float rounding of the
// result, as interpolationErrorBound(); with the default 4096 nodes and the bundled calibration that is
// 1.2e-6 in f, below the 1 / 184,320 = 5.4e-6 step of the blue-noise thresholds.
class FractionMap {
public:
  // Throws std::invalid_argument for fewer than 2 nodes.
  explicit FractionMap(const calibration::Calibration& calibration, std::size_t nodes = 4096);

  // Const, thread-safe, allocation-free.
  calibration::FractionResult fraction(double modulusMpa) const {
    if (!(modulusMpa >= floorMpa_)) return {floorFraction_, calibration::Clamp::BelowFloor};  // also NaN
    if (modulusMpa > maxModulusMpa_) return {1.0, calibration::Clamp::AboveMax};
    const double x = (std::log(modulusMpa) - lnFloor_) * inverseStep_;
    const auto node = std::min(static_cast<std::size_t>(x), table_.size() - 2);
    const double t = x - static_cast<double>(node);
    return {table_[node] + t * (table_[node + 1] - table_[node]), calibration::Clamp::None};
  }

  double interpolationErrorBound() const { return errorBound_; }
  double floorMpa() const { return floorMpa_; }
  double floorFraction() const { return floorFraction_; }
  double maxModulusMpa() const { return maxModulusMpa_; }
  std::size_t nodes() const { return table_.size(); }

private:
  std::vector<double> table_;
  double floorMpa_, floorFraction_, maxModulusMpa_, lnFloor_, inverseStep_;
  double errorBound_ = 0.0;
};

struct MappingStats {
  std::uint64_t voxels = 0;
  calibration::ClampCounts clamps;  // belowFloor: E < floor (set to the floor's fraction); aboveMax: E > max
};

// Maps the active voxels of layers [k0, k1) (active tiles included); counts clamps per leaf in
// parallel and sums them, so `stats` is the same for any thread count. Throws std::invalid_argument
// for k0 > k1.
openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, int k0, int k1,
                                       MappingStats& stats);
// The whole grid.
openvdb::FloatGrid::Ptr mapToFractions(const openvdb::FloatGrid& modulus, const FractionMap& map, MappingStats& stats);

}  // namespace rodfab::materials
