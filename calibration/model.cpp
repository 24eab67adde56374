#include "calibration/model.hpp"

#include <boost/math/tools/toms748_solve.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace rodfab::calibration {

namespace {

std::string mpa(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g MPa", v);
  return buf;
}

void requireModulus(double v, const char* what) {
  if (!std::isfinite(v) || !(v > 0.0)) throw std::invalid_argument(std::string(what) + " must be a finite modulus > 0, got " + mpa(v));
}

// Shape-preserving one-sided slope at an end node from its two adjacent secants m0 (nearer) and m1.
double endSlope(double h0, double h1, double m0, double m1) {
  const double d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1);
  if (std::signbit(d) != std::signbit(m0) || d == 0.0 || m0 == 0.0) return 0.0;
  if (std::signbit(m0) != std::signbit(m1) && std::abs(d) > 3.0 * std::abs(m0)) return 3.0 * m0;
  return d;
}

}  // namespace

std::string_view modelName(Model model) {
  switch (model) {
    case Model::Pchip: return "pchip";
    case Model::Lichtenecker: return "lichtenecker";
    case Model::LogPower: return "log-power";
  }
  return "?";
}

std::optional<Model> parseModel(std::string_view name) {
  for (Model m : {Model::Pchip, Model::Lichtenecker, Model::LogPower})
    if (modelName(m) == name) return m;
  return std::nullopt;
}

std::vector<double> pchipSlopes(const std::vector<double>& x, const std::vector<double>& y) {
  const std::size_t n = x.size();
  if (n < 2 || y.size() != n) throw std::invalid_argument("pchip needs at least two nodes and one value per node");
  std::vector<double> h(n - 1), m(n - 1), slopes(n);
  for (std::size_t k = 0; k + 1 < n; ++k) {
    h[k] = x[k + 1] - x[k];
    m[k] = (y[k + 1] - y[k]) / h[k];
  }
  if (n == 2) return {m[0], m[0]};  // a straight line
  for (std::size_t k = 1; k + 1 < n; ++k) {
    if (m[k - 1] * m[k] <= 0.0) {
      slopes[k] = 0.0;  // a local extremum of the data stays one
      continue;
    }
    const double w1 = 2.0 * h[k] + h[k - 1];
    const double w2 = h[k] + 2.0 * h[k - 1];
    slopes[k] = (w1 + w2) / (w1 / m[k - 1] + w2 / m[k]);
  }
  slopes[0] = endSlope(h[0], h[1], m[0], m[1]);
  slopes[n - 1] = endSlope(h[n - 2], h[n - 3], m[n - 2], m[n - 3]);
  return slopes;
}

Calibration::Calibration(ModelParameters parameters, double floorMpa, FitRecord record)
    : parameters_(std::move(parameters)), record_(std::move(record)) {
  ModelParameters& p = parameters_;
  if (p.model == Model::Pchip) {
    if (p.fractions.size() < 2 || p.fractions.size() != p.moduliMpa.size())
      throw std::invalid_argument("pchip needs at least two (fraction, modulus) nodes");
    if (p.fractions.front() != 0.0 || p.fractions.back() != 1.0)
      throw std::invalid_argument("pchip nodes must run from Vero fraction 0 to 1");
    for (std::size_t i = 0; i < p.fractions.size(); ++i) {
      requireModulus(p.moduliMpa[i], "a pchip node modulus");
      if (i > 0 && !(p.fractions[i] > p.fractions[i - 1]))
        throw std::invalid_argument("pchip node fractions must be strictly increasing");
      if (i > 0 && !(p.moduliMpa[i] > p.moduliMpa[i - 1]))
        throw std::invalid_argument("pchip node moduli must be strictly increasing with the fraction");
      lnModuli_.push_back(std::log(p.moduliMpa[i]));
    }
    std::vector<double> x = p.fractions, y = lnModuli_, s = pchipSlopes(p.fractions, lnModuli_);
    pchip_.emplace(std::move(x), std::move(y), std::move(s));
    p.tangoModulusMpa = p.moduliMpa.front();
    p.veroModulusMpa = p.moduliMpa.back();
    p.exponent = 0.0;
  } else {
    requireModulus(p.tangoModulusMpa, "the Tango (0 % Vero) modulus");
    requireModulus(p.veroModulusMpa, "the Vero (100 % Vero) modulus");
    if (!(p.veroModulusMpa > p.tangoModulusMpa))
      throw std::invalid_argument("the Vero modulus (" + mpa(p.veroModulusMpa) + ") must exceed the Tango modulus (" +
                                  mpa(p.tangoModulusMpa) + ")");
    if (!std::isfinite(p.exponent) || (p.model == Model::LogPower && !(p.exponent > 0.0)))
      throw std::invalid_argument(std::string("the ") + std::string(modelName(p.model)) + " exponent must be finite" +
                                  (p.model == Model::LogPower ? " and > 0" : ""));
    p.fractions.clear();
    p.moduliMpa.clear();
  }
  lnTango_ = std::log(p.tangoModulusMpa);
  lnRatio_ = std::log(p.veroModulusMpa) - lnTango_;
  // E(0) and E(1) are the end moduli themselves: exp(log(x)) may be off by an ulp, which would put a
  // floor equal to E(0) (as the fit's evaluator uses) below the range.
  minModulusMpa_ = p.tangoModulusMpa;
  maxModulusMpa_ = p.veroModulusMpa;
  if (!std::isfinite(floorMpa) || floorMpa < minModulusMpa_ || floorMpa >= maxModulusMpa_)
    throw std::invalid_argument("the floor (" + mpa(floorMpa) + ") must lie from the modulus at 0 % Vero (" +
                                mpa(minModulusMpa_) + ") up to, not including, the modulus at 100 % Vero (" +
                                mpa(maxModulusMpa_) + ")");
  floorMpa_ = floorMpa;
  floorFraction_ = invertLn(std::log(floorMpa));
}

double Calibration::lnModulus(double f) const {
  if (std::isnan(f)) return f;
  f = std::clamp(f, 0.0, 1.0);
  const double a = parameters_.exponent;
  switch (parameters_.model) {
    case Model::Pchip: return (*pchip_)(f);
    // log1p/expm1 keep the power mean accurate as the exponent approaches its geometric-mean limit 0.
    case Model::Lichtenecker:
      return a == 0.0 ? lnTango_ + f * lnRatio_ : lnTango_ + std::log1p(f * std::expm1(a * lnRatio_)) / a;
    case Model::LogPower: return lnTango_ + lnRatio_ * std::pow(f, a);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

double Calibration::modulusMpa(double f) const { return std::exp(lnModulus(f)); }

double Calibration::invertLn(double lnTarget) const {
  const double a = parameters_.exponent;
  const double u = lnTarget - lnTango_;  // ln(E / E_T), in [0, lnRatio_]
  switch (parameters_.model) {
    case Model::Lichtenecker:
      return std::clamp(a == 0.0 ? u / lnRatio_ : std::expm1(a * u) / std::expm1(a * lnRatio_), 0.0, 1.0);
    case Model::LogPower: return std::clamp(std::pow(u / lnRatio_, 1.0 / a), 0.0, 1.0);
    case Model::Pchip: break;
  }
  // The curve is monotone, so the node interval holding the target is found by value, and TOMS 748
  // (bracketing, superlinear) solves within it.
  const auto& x = parameters_.fractions;
  const auto& y = lnModuli_;
  std::size_t i = static_cast<std::size_t>(std::upper_bound(y.begin(), y.end(), lnTarget) - y.begin());
  i = std::clamp<std::size_t>(i, 1, y.size() - 1) - 1;
  if (lnTarget <= y[i]) return x[i];
  if (lnTarget >= y[i + 1]) return x[i + 1];
  const auto residual = [&](double f) { return (*pchip_)(f) - lnTarget; };
  const auto closeEnough = [](double lo, double hi) { return hi - lo <= 1e-12; };
  std::uintmax_t iterations = 200;
  const auto [lo, hi] = boost::math::tools::toms748_solve(residual, x[i], x[i + 1], y[i] - lnTarget, y[i + 1] - lnTarget,
                                                          closeEnough, iterations);
  return 0.5 * (lo + hi);
}

FractionResult Calibration::fraction(double modulusMpa) const {
  if (!(modulusMpa >= floorMpa_)) return {floorFraction_, Clamp::BelowFloor};  // also NaN
  if (modulusMpa > maxModulusMpa_) return {1.0, Clamp::AboveMax};
  if (modulusMpa == floorMpa_) return {floorFraction_, Clamp::None};
  return {invertLn(std::log(modulusMpa)), Clamp::None};
}

}  // namespace rodfab::calibration
