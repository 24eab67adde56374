#include "slicer/fit_summary.hpp"

#include <cmath>
#include <cstdio>
#include <map>
#include <string>

namespace rodfab::cli {

void printCalibrationFit(const calibration::Calibration& c) {
  const calibration::FitRecord& r = c.record();
  const calibration::FitQuality& q = r.quality;
  std::printf("data:          %s (%zu measurements at %zu fractions; sha256 %s)\n", r.dataFile.c_str(), q.measurements,
              q.fractions, r.dataSha256.c_str());
  if (r.temperatureC) std::printf("temperature:   %g C\n", *r.temperatureC);
  else std::printf("temperature:   not given in the data\n");
  std::printf("dither:        %s\n", r.dither.empty() ? "not given in the data" : r.dither.c_str());
  std::printf("materials:     %s\n", r.rigidMaterial.empty() ? "not recorded (--materials RIGID,RUBBERY)"
                                                              : (r.rigidMaterial + " (rigid), " + r.rubberyMaterial + " (rubbery)").c_str());
  std::printf("model:         %s\n", std::string(calibration::modelName(c.model())).c_str());
  if (c.model() == calibration::Model::Lichtenecker) std::printf("exponent:      a = %.6f\n", c.parameters().exponent);
  if (c.model() == calibration::Model::LogPower) std::printf("exponent:      n = %.6f\n", c.parameters().exponent);

  std::map<double, std::pair<double, int>> groups;  // fraction -> (sum of ln E, count)
  for (const auto& m : r.measurements) {
    auto& g = groups[m.veroFraction];
    g.first += std::log(m.modulusMpa);
    g.second += 1;
  }
  std::printf("\n  %7s  %3s  %12s  %12s  %9s\n", "Vero %", "n", "mean MPa", "fit MPa", "fit/mean");
  for (const auto& [f, g] : groups) {
    const double mean = std::exp(g.first / g.second);
    const double fitted = c.modulusMpa(f);
    std::printf("  %7.2f  %3d  %12.4f  %12.4f  %+8.2f%%\n", 100 * f, g.second, mean, fitted, 100 * (fitted / mean - 1));
  }
  std::printf("  (means are geometric means, as the fit is in ln E)\n\n");
  std::printf("floor:         %g MPa -> %.4f %% Vero (requests below it are raised to it)\n", c.floorMpa(), 100 * c.floorFraction());
  std::printf("maximum:       %g MPa at 100 %% Vero (requests above it get 100 %%)\n", c.maxModulusMpa());
  std::printf("fit quality:   RMS error %.4f in ln E, R^2 %.4f in ln E, max relative error %.2f %%\n", q.rmsLn, q.r2Ln,
              100 * q.maxRelativeError);
  const std::size_t interior = q.fractions >= 2 ? q.fractions - 2 : 0;
  if (q.leaveOneOutRmsLn && q.leaveOneOutFractions < interior)
    std::printf("leave-one-out: RMS error %.4f in ln E (%zu of the %zu interior fractions, evenly spaced, each predicted "
                "without its coupons)\n", *q.leaveOneOutRmsLn, q.leaveOneOutFractions, interior);
  else if (q.leaveOneOutRmsLn)
    std::printf("leave-one-out: RMS error %.4f in ln E (each interior fraction predicted without its coupons)\n", *q.leaveOneOutRmsLn);
  else
    std::printf("leave-one-out: not enough fractions\n");
}

}  // namespace rodfab::cli
