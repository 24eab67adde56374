#include "calibration/fit.hpp"

#include <boost/algorithm/string/join.hpp>
#include <boost/math/tools/minima.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <vector>

namespace rodfab::calibration {

namespace {

// Replicates at one Vero fraction.
struct Group {
  double fraction = 0.0;
  double meanLn = 0.0;  // mean of ln E: the least-squares value in ln E
  std::vector<const Measurement*> rows;
};

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string describe(const Group& g) {
  return fmt("%g", g.fraction) + " (" + fmt("%.4g", std::exp(g.meanLn)) + " MPa, " + std::to_string(g.rows.size()) +
         (g.rows.size() == 1 ? " specimen, line " : " specimens, first at line ") + std::to_string(g.rows.front()->line) + ")";
}

// The geometric mean; a lone specimen keeps its value exactly (exp(log(x)) may be off by an ulp).
double meanModulus(const Group& g) { return g.rows.size() == 1 ? g.rows.front()->modulusMpa : std::exp(g.meanLn); }

std::vector<Group> groupByFraction(const std::vector<Measurement>& measurements) {
  std::map<double, Group> byFraction;
  for (const Measurement& m : measurements) {
    Group& g = byFraction[m.veroFraction];
    g.fraction = m.veroFraction;
    g.rows.push_back(&m);
  }
  std::vector<Group> groups;
  for (auto& [f, g] : byFraction) {
    double sum = 0.0;
    for (const Measurement* m : g.rows) sum += std::log(m->modulusMpa);
    g.meanLn = sum / static_cast<double>(g.rows.size());
    groups.push_back(std::move(g));
  }
  return groups;
}

// An E(f) evaluator for parameters alone; any floor inside the range does, E(0) is always inside.
Calibration evaluator(const ModelParameters& p) {
  const double e0 = p.model == Model::Pchip ? p.moduliMpa.front() : p.tangoModulusMpa;
  return Calibration(p, e0);
}

struct Search {
  double lo, hi;       // over the search variable
  bool logExponent;    // the variable is ln(exponent)
};

// Where each model's exponent is sought: power means of order -4..4 cover every two-phase composite
// between the series and parallel bounds seen in practice; log-power exponents from 1/50 to 50.
Search searchRange(Model model) {
  if (model == Model::Lichtenecker) return {-4.0, 4.0, false};
  return {std::log(0.02), std::log(50.0), true};
}

struct ExponentFit {
  double exponent;
  bool atSearchEdge;
};

// The sum of squares in ln E over every measurement, up to a constant: each group's replicates
// scatter about their mean ln E independently of the model, so a group counts as its mean weighted by
// its size (one evaluation per fraction, not per row).
double groupedSquares(const Calibration& c, const std::vector<Group>& groups) {
  double sum = 0.0;
  for (const Group& g : groups) {
    const double r = g.meanLn - c.lnModulus(g.fraction);
    sum += static_cast<double>(g.rows.size()) * r * r;
  }
  return sum;
}

// Minimizes over [lo, hi] of the search variable; `near` skips the scan (a refit from a nearby optimum).
ExponentFit fitExponent(Model model, const std::vector<Group>& groups, std::optional<double> near = std::nullopt) {
  ModelParameters p;
  p.model = model;
  p.tangoModulusMpa = meanModulus(groups.front());
  p.veroModulusMpa = meanModulus(groups.back());
  const Search range = searchRange(model);
  const auto sumOfSquares = [&](double variable) {
    p.exponent = range.logExponent ? std::exp(variable) : variable;
    return groupedSquares(evaluator(p), groups);
  };
  // The scan finds the basin of the global minimum even if the sum of squares has several; Brent then
  // polishes within the two neighbouring scan intervals.
  constexpr int kScan = 160;
  const double step = (range.hi - range.lo) / kScan;
  double lo, hi;
  if (near) {
    const double v = range.logExponent ? std::log(*near) : *near;
    lo = std::max(range.lo, v - step), hi = std::min(range.hi, v + step);
  } else {
    int best = 0;
    double bestValue = std::numeric_limits<double>::infinity();
    for (int k = 0; k <= kScan; ++k) {
      const double value = sumOfSquares(range.lo + k * step);
      if (value < bestValue) bestValue = value, best = k;
    }
    lo = range.lo + std::max(best - 1, 0) * step;
    hi = range.lo + std::min(best + 1, kScan) * step;
  }
  std::uintmax_t iterations = 200;
  const auto [variable, value] =
      boost::math::tools::brent_find_minima(sumOfSquares, lo, hi, std::numeric_limits<double>::digits / 2, iterations);
  (void)value;
  // A refit whose optimum ran to the edge of its small bracket has moved further: search again whole.
  if (near && ((variable - lo < 1e-6 * step && lo > range.lo) || (hi - variable < 1e-6 * step && hi < range.hi)))
    return fitExponent(model, groups);
  // Brent never evaluates closer to a bound than its tolerance (~1e-7 of the exponent here), so an
  // optimum run into the edge lands that far inside it: within a thousandth of a scan step is at it
  // (1e-6 of a step missed the lower edges: a Lichtenecker a = -10 fitted as -4.000000).
  const bool atEdge = variable - range.lo < 1e-3 * step || range.hi - variable < 1e-3 * step;
  return {range.logExponent ? std::exp(variable) : variable, atEdge};
}

// Parameters from groups already checked for ends at 0 and 1 and enough fractions for the model.
ModelParameters fitParameters(Model model, const std::vector<Group>& groups, bool* atSearchEdge = nullptr,
                              std::optional<double> nearExponent = std::nullopt) {
  ModelParameters p;
  p.model = model;
  if (model == Model::Pchip) {
    for (const Group& g : groups) {
      p.fractions.push_back(g.fraction);
      p.moduliMpa.push_back(meanModulus(g));
    }
    return p;
  }
  const ExponentFit e = fitExponent(model, groups, nearExponent);
  p.tangoModulusMpa = meanModulus(groups.front());
  p.veroModulusMpa = meanModulus(groups.back());
  p.exponent = e.exponent;
  if (atSearchEdge) *atSearchEdge = e.atSearchEdge;
  return p;
}

std::size_t minimumFractions(Model model) { return model == Model::Pchip ? 2 : 3; }

FitQuality assess(const Calibration& c, Model model, const std::vector<Group>& groups) {
  FitQuality q;
  q.fractions = groups.size();
  double sumLn = 0.0;
  for (const Group& g : groups)
    for (const Measurement* m : g.rows) sumLn += std::log(m->modulusMpa), ++q.measurements;
  const double meanLn = sumLn / static_cast<double>(q.measurements);
  double residualSquares = 0.0, totalSquares = 0.0;
  for (const Group& g : groups)
    for (const Measurement* m : g.rows) {
      const double lnE = std::log(m->modulusMpa);
      const double r = lnE - c.lnModulus(m->veroFraction);
      residualSquares += r * r;
      totalSquares += (lnE - meanLn) * (lnE - meanLn);
      q.maxRelativeError = std::max(q.maxRelativeError, std::abs(c.modulusMpa(m->veroFraction) - m->modulusMpa) / m->modulusMpa);
    }
  q.rmsLn = std::sqrt(residualSquares / static_cast<double>(q.measurements));
  q.r2Ln = totalSquares > 0.0 ? 1.0 - residualSquares / totalSquares : 1.0;

  // Leave out one interior fraction (all its replicates) at a time: replicates would otherwise vouch
  // for each other, and the end fractions cannot go (the curve is never extrapolated).
  if (groups.size() >= minimumFractions(model) + 1) {
    const std::size_t interior = groups.size() - 2;
    // A parametric refit costs about one evaluation per group per Brent step, so all n refits cost n^2:
    // beyond the budget, leave out an evenly spaced sample (a fixed rule: the same data give the same sample).
    constexpr std::size_t kEvaluationBudget = 4'000'000;
    const std::size_t sampled =
        model == Model::Pchip ? interior : std::clamp<std::size_t>(kEvaluationBudget / groups.size(), 1, interior);
    double looSquares = 0.0;
    std::size_t looCount = 0;
    for (std::size_t i = 0; i < sampled; ++i) {
      const std::size_t left = 1 + i * interior / sampled;
      std::vector<Group> rest;
      rest.reserve(groups.size() - 1);
      for (std::size_t k = 0; k < groups.size(); ++k)
        if (k != left) rest.push_back(groups[k]);
      // The full fit's exponent is a close start: one group moves the optimum little.
      const Calibration without = evaluator(fitParameters(model, rest, nullptr, c.parameters().exponent));
      for (const Measurement* m : groups[left].rows) {
        const double r = std::log(m->modulusMpa) - without.lnModulus(m->veroFraction);
        looSquares += r * r;
        ++looCount;
      }
    }
    q.leaveOneOutRmsLn = std::sqrt(looSquares / static_cast<double>(looCount));
    q.leaveOneOutFractions = sampled;
  }
  return q;
}

// The process the measurements describe, recorded in `record`: their (single) training temperature
// and ditherer. Throws FitError when they mix temperatures (more than 1 C apart) or ditherers.
void recordProcess(FitRecord& record, const std::string& where) {
  // One calibration describes one printing process at one training temperature.
  const Measurement* coolest = nullptr;
  const Measurement* warmest = nullptr;
  double temperatureSum = 0.0;
  std::size_t temperatures = 0;
  std::map<std::string, int> dithers;  // ditherer -> first line
  for (const Measurement& m : record.measurements) {
    if (m.temperatureC) {
      if (!coolest || *m.temperatureC < *coolest->temperatureC) coolest = &m;
      if (!warmest || *m.temperatureC > *warmest->temperatureC) warmest = &m;
      temperatureSum += *m.temperatureC;
      ++temperatures;
    }
    if (!m.dither.empty()) dithers.emplace(m.dither, m.line);
  }
  if (temperatures > 0) {
    if (*warmest->temperatureC - *coolest->temperatureC > 1.0)
      throw FitError(where + "the coupons were measured at different temperatures (" + fmt("%g", *coolest->temperatureC) +
                     " C at line " + std::to_string(coolest->line) + ", " + fmt("%g", *warmest->temperatureC) +
                     " C at line " + std::to_string(warmest->line) +
                     "); a calibration holds at one training temperature: fit each temperature on its own");
    record.temperatureC = temperatureSum / static_cast<double>(temperatures);
  }
  if (dithers.size() > 1) {
    std::vector<std::string> each;
    for (const auto& [name, line] : dithers) each.push_back("'" + name + "' at line " + std::to_string(line));
    throw FitError(where + "the coupons come from different ditherers (" + boost::algorithm::join(each, ", ") +
                   "); the modulus depends on the ditherer: fit each one on its own");
  }
  if (!dithers.empty()) record.dither = dithers.begin()->first;
}

// Throws FitError unless the groups span pure Tango to pure Vero, stiffen from one to the other, hold
// enough fractions for `model` and, for pchip, stiffen at every step.
void checkGroups(const std::vector<Group>& groups, Model model, const std::string& where) {
  if (groups.front().fraction != 0.0)
    throw FitError(where + "no coupon at vero_fraction 0 (pure Tango); the lowest fraction measured is " + describe(groups.front()) +
                   ". The curve is never extrapolated: measure both pure materials");
  if (groups.back().fraction != 1.0)
    throw FitError(where + "no coupon at vero_fraction 1 (pure Vero); the highest fraction measured is " + describe(groups.back()) +
                   ". The curve is never extrapolated: measure both pure materials");
  if (!(groups.back().meanLn > groups.front().meanLn))
    throw FitError(where + "pure Vero " + describe(groups.back()) + " is not stiffer than pure Tango " + describe(groups.front()));
  if (groups.size() < minimumFractions(model))
    throw FitError(where + "the " + std::string(modelName(model)) +
                   " exponent needs measurements at a third Vero fraction between 0 and 1");
  if (model == Model::Pchip) {
    std::string offending;
    for (std::size_t k = 0; k + 1 < groups.size(); ++k)
      if (!(groups[k + 1].meanLn > groups[k].meanLn))
        offending += "\n  " + describe(groups[k]) + " -> " + describe(groups[k + 1]);
    if (!offending.empty())
      throw FitError(where + "the mean modulus does not strictly increase with the Vero fraction at:" + offending +
                     "\nCheck or remeasure those coupons, or fit a parametric model (lichtenecker or log-power), "
                     "which is monotone by construction and fits such data by least squares");
  }
}

}  // namespace

Calibration fitCalibration(const DataSet& data, const FitOptions& options) {
  const std::string where = data.source + ": ";
  if (data.measurements.empty()) throw FitError(where + "no measurements to fit");
  if (!std::isfinite(options.floorMpa) || !(options.floorMpa > 0.0))
    throw FitError(where + "the floor must be a modulus > 0 MPa, got " + fmt("%g", options.floorMpa));

  FitRecord record;
  record.dataFile = data.source;
  record.dataSha256 = data.sha256;
  record.measurements = data.measurements;

  recordProcess(record, where);
  const std::vector<Group> groups = groupByFraction(record.measurements);
  checkGroups(groups, options.model, where);

  bool atSearchEdge = false;
  ModelParameters parameters = fitParameters(options.model, groups, &atSearchEdge);
  if (atSearchEdge) {
    const Search range = searchRange(options.model);
    const double lo = range.logExponent ? std::exp(range.lo) : range.lo;
    const double hi = range.logExponent ? std::exp(range.hi) : range.hi;
    throw FitError(where + "the best " + std::string(modelName(options.model)) + " exponent lies at the edge of its range [" +
                   fmt("%g", lo) + ", " + fmt("%g", hi) + "]: the model does not describe these data; try pchip");
  }
  const Calibration shape = evaluator(parameters);
  if (options.floorMpa < shape.minModulusMpa() || options.floorMpa >= shape.maxModulusMpa())
    throw FitError(where + "the floor " + fmt("%g", options.floorMpa) + " MPa lies outside the printable range: it must be at least " +
                   fmt("%g", shape.minModulusMpa()) + " MPa (0 % Vero) and below " + fmt("%g", shape.maxModulusMpa()) +
                   " MPa (100 % Vero)");
  record.quality = assess(shape, options.model, groups);
  return Calibration(std::move(parameters), options.floorMpa, std::move(record));
}

}  // namespace rodfab::calibration
