#include "calibration/calibration.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>

namespace rodfab::cli {

namespace {

constexpr const char* kSynopsis =
    "DATA.csv [--model pchip|lichtenecker|log-power] [--floor-mpa 8] [--output CAL.json] [--plot FIT.png] [--materials RIGID,RUBBERY]";

void printFit(const calibration::Calibration& c) {
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

}  // namespace

int runCalibrate(const std::vector<std::string>& args) {
  po::options_description options("options");
  options.add_options()
      ("data", po::value<std::string>()->required(), "DMA measurements (CSV: vero_fraction, modulus_mpa, ...)")
      ("model", po::value<std::string>()->default_value("pchip"), "pchip, lichtenecker or log-power")
      ("floor-mpa", po::value<double>()->default_value(calibration::kDefaultFloorMpa),
       "minimum modulus that keeps shape fixity at room temperature (MPa)")
      ("output,o", po::value<std::string>(), "write the calibration file (JSON) here")
      ("plot", po::value<std::string>(), "write a PNG plot of the fit here")
      ("materials", po::value<std::string>(),
       "RIGID,RUBBERY: the materials the coupons were printed in, as the printer profile names them "
       "(e.g. VeroUltraWhite,Agilus30Black); recorded so that slice refuses the calibration for other materials");
  po::positional_options_description positional;
  positional.add("data", 1);
  po::variables_map vm;
  if (auto code = parseOptions("calibrate", kSynopsis, options, positional, args, vm)) return *code;

  const std::string modelText = vm["model"].as<std::string>();
  const auto model = calibration::parseModel(modelText);
  const double floorMpa = vm["floor-mpa"].as<double>();
  std::string usageError;
  if (!model) usageError = "--model: expected pchip, lichtenecker or log-power, got '" + modelText + "'";
  else if (!std::isfinite(floorMpa) || !(floorMpa > 0)) usageError = "--floor-mpa: expected a modulus > 0 MPa";
  std::string rigid, rubbery;
  if (vm.count("materials")) {
    const std::string text = vm["materials"].as<std::string>();
    const std::size_t comma = text.find(',');
    if (comma != std::string::npos) rigid = text.substr(0, comma), rubbery = text.substr(comma + 1);
    if (rigid.empty() || rubbery.empty() || rubbery.find(',') != std::string::npos)
      usageError = "--materials: expected RIGID,RUBBERY (two material names), got '" + text + "'";
  }
  if (!usageError.empty()) {
    std::cerr << "rodfab calibrate: " << usageError << "\nusage: rodfab calibrate " << kSynopsis << '\n';
    return kUsage;
  }

  commandLineAccepted();
  const std::string file = vm["data"].as<std::string>();
  if (vm.count("output") && vm.count("plot") && vm["output"].as<std::string>() == vm["plot"].as<std::string>())
    return cli::usageError("calibrate", "--output and --plot name the same file");
  // Existing outputs are replaced only when rodfab wrote them (a calibration file, a fit plot).
  if (vm.count("output") && !outputAllowed(vm["output"].as<std::string>(), {file},
                                           {"calibration file", true, "", calibration::isCalibrationFile}))
    return kFailed;
  if (vm.count("plot") &&
      !outputAllowed(vm["plot"].as<std::string>(), {file}, {"fit plot", true, "", calibration::isFitPlot}))
    return kFailed;
  calibration::DataSet data;
  try {
    data = calibration::readData(file);
  } catch (const calibration::DataError& e) {
    std::cerr << e.what() << '\n'
              << file << ": " << e.issues().size() << (e.issues().size() == 1 ? " error" : " errors") << "; nothing fitted\n";
    return kFailed;
  }
  calibration::Calibration fit = calibration::fitCalibration(data, {*model, floorMpa});
  if (!rigid.empty()) {
    calibration::FitRecord record = fit.record();
    record.rigidMaterial = rigid;
    record.rubberyMaterial = rubbery;
    fit = calibration::Calibration(fit.parameters(), fit.floorMpa(), std::move(record));
  }
  printFit(fit);
  if (vm.count("output")) {
    calibration::writeCalibration(fit, vm["output"].as<std::string>());
    std::printf("wrote:         %s\n", vm["output"].as<std::string>().c_str());
  }
  if (vm.count("plot")) {
    calibration::writeFitPlot(fit, vm["plot"].as<std::string>());
    std::printf("wrote:         %s\n", vm["plot"].as<std::string>().c_str());
  }
  return kOk;
}

}  // namespace rodfab::cli
