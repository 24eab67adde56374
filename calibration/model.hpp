// The calibration: the forward model E(f) (modulus in MPa at Vero fraction f), its inverse f(E) with
// the floor and the clamping it implies, and the record of the fit it came from.
#pragma once

#include "calibration/data.hpp"

#include <boost/math/interpolators/cubic_hermite.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rodfab::calibration {

// The minimum modulus that keeps shape fixity at room temperature (about 30 % Vero at 60 C).
inline constexpr double kDefaultFloorMpa = 8.0;

enum class Model : std::uint8_t {
  Pchip,         // monotone piecewise-cubic Hermite interpolation of ln E through the per-fraction means
  Lichtenecker,  // E^a = (1-f) E_T^a + f E_V^a  (a = 0: ln E linear in f)
  LogPower,      // ln E = ln E_T + ln(E_V / E_T) f^n
};

std::string_view modelName(Model model);  // "pchip", "lichtenecker", "log-power"
std::optional<Model> parseModel(std::string_view name);

// What defines E(f). The fit derives them from per-fraction means taken in ln E (geometric means of
// the moduli), the statistic that least squares in ln E picks for a group of replicates.
struct ModelParameters {
  Model model = Model::Pchip;
  // pchip: the nodes the curve passes through, fractions strictly increasing from 0 to 1.
  std::vector<double> fractions;
  std::vector<double> moduliMpa;
  // lichtenecker and log-power: the end moduli (the means at f = 0 and f = 1) and the fitted exponent.
  double tangoModulusMpa = 0.0;
  double veroModulusMpa = 0.0;
  double exponent = 0.0;
};

struct FitQuality {
  std::size_t measurements = 0;
  std::size_t fractions = 0;      // distinct Vero fractions
  double rmsLn = 0.0;             // RMS of ln E_measured - ln E_fit over all measurements
  double r2Ln = 0.0;              // coefficient of determination in ln E
  double maxRelativeError = 0.0;  // max |E_fit - E_measured| / E_measured
  // RMS in ln E of predicting each interior fraction's measurements from a fit without that fraction;
  // absent when too few fractions remain (pchip needs 3 fractions, the parametric models 4).
  std::optional<double> leaveOneOutRmsLn;
  // How many interior fractions were left out for it: all of them, unless the parametric refits would
  // exceed a fixed amount of work (about 4 million model evaluations), then an evenly spaced sample.
  // Known only right after a fit (not stored in calibration files).
  std::size_t leaveOneOutFractions = 0;
};

// Where a calibration came from.
struct FitRecord {
  std::string dataFile;
  std::string dataSha256;
  std::vector<Measurement> measurements;
  std::optional<double> temperatureC;  // mean DMA temperature of the coupons, when the data gives it
  std::string dither;                  // ditherer of the coupons; empty when the data does not say
  // The rigid and rubbery materials the coupons were printed in (a printer profile's names, e.g.
  // VeroWhitePlus and TangoBlackPlus); both empty when the file does not record them.
  std::string rigidMaterial, rubberyMaterial;
  FitQuality quality;
};

enum class Clamp : std::uint8_t {
  None,
  BelowFloor,  // the request was below the floor (or not a number): the floor's fraction was used
  AboveMax,    // the request was above the modulus at 100 % Vero: 100 % was used
};

struct FractionResult {
  double fraction;
  Clamp clamp;
};

// Per-thread clamp tallies that callers sum, so no query touches shared state.
struct ClampCounts {
  std::uint64_t belowFloor = 0;
  std::uint64_t aboveMax = 0;

  void count(Clamp c) {
    belowFloor += c == Clamp::BelowFloor;
    aboveMax += c == Clamp::AboveMax;
  }
  std::uint64_t total() const { return belowFloor + aboveMax; }
  ClampCounts& operator+=(const ClampCounts& other) {
    belowFloor += other.belowFloor;
    aboveMax += other.aboveMax;
    return *this;
  }
};

// Immutable once built; every query is const, thread-safe and allocation-free.
class Calibration {
public:
  // Throws std::invalid_argument for parameters that do not make a strictly increasing E(f) on [0, 1]
  // or a floor outside [E(0), E(1)).
  Calibration(ModelParameters parameters, double floorMpa, FitRecord record = {});

  // ln E(f) and E(f) in MPa; f is clamped to [0, 1].
  double lnModulus(double fraction) const;
  double modulusMpa(double fraction) const;

  // The Vero fraction that gives `modulusMpa`, to 1e-9 in f. Below the floor: the floor's fraction;
  // above maxModulusMpa(): 1; the clamp says which happened.
  FractionResult fraction(double modulusMpa) const;

  double floorMpa() const { return floorMpa_; }
  double floorFraction() const { return floorFraction_; }
  double minModulusMpa() const { return minModulusMpa_; }  // E(0)
  double maxModulusMpa() const { return maxModulusMpa_; }  // E(1), the stiffest the printer makes
  Model model() const { return parameters_.model; }
  const ModelParameters& parameters() const { return parameters_; }
  const FitRecord& record() const { return record_; }

private:
  // Solves lnModulus(f) = lnTarget for f in [0, 1]; lnTarget within [ln E(0), ln E(1)].
  double invertLn(double lnTarget) const;

  ModelParameters parameters_;
  FitRecord record_;
  std::vector<double> lnModuli_;  // pchip: ln of the node moduli, to find a node interval by value
  std::optional<boost::math::interpolators::cubic_hermite<std::vector<double>>> pchip_;
  double lnTango_ = 0.0;
  double lnRatio_ = 0.0;  // ln(E_V / E_T)
  double floorMpa_ = 0.0;
  double floorFraction_ = 0.0;
  double minModulusMpa_ = 0.0;
  double maxModulusMpa_ = 0.0;
};

// The PCHIP node slopes (Fritsch-Butland weighted harmonic means inside, shape-preserving one-sided
// three-point formulas at the ends, as in MATLAB's and SciPy's pchip): monotone data give a monotone
// curve. Boost's own pchip needs four points; calibration sets often have three fractions.
std::vector<double> pchipSlopes(const std::vector<double>& x, const std::vector<double>& y);

}  // namespace rodfab::calibration
