// rodfab calibrate: modulus against Vero fraction fitted to DMA data, written as a calibration file
// and a plot (calibration/ fits; slicer/fit_summary.hpp prints the fit).
#include "calibration/calibration.hpp"
#include "common/located_issues.hpp"
#include "materials/ditherer.hpp"
#include "slicer/command.hpp"
#include "slicer/fit_summary.hpp"
#include "slicer/options.hpp"
#include "slicer/value_parsers.hpp"

#include <cmath>
#include <cstdio>
#include <iostream>
#include <variant>

namespace rodfab::cli {

namespace {

void addCalibrateOptions(po::options_description& options) {
  options.add_options()
      ("data", po::value<std::string>()->required()->value_name("DATA.csv"), "DMA measurements (CSV: vero_fraction, modulus_mpa, ...)")
      ("model", po::value<std::string>()->default_value("pchip")->value_name("pchip|lichtenecker|log-power"), "pchip, lichtenecker or log-power")
      ("floor-mpa", po::value<double>()->default_value(calibration::kDefaultFloorMpa)->value_name("MPA"),
       "minimum modulus that keeps shape fixity at room temperature (MPa)")
      ("output,o", po::value<std::string>()->value_name("CAL.json"), "write the calibration file (JSON) here")
      ("plot", po::value<std::string>()->value_name("FIT.png"), "write a PNG plot of the fit here")
      ("materials", po::value<std::string>()->value_name("RIGID,RUBBERY"),
       "RIGID,RUBBERY: the materials the coupons were printed in, as the printer profile names them "
       "(e.g. VeroUltraWhite,Agilus30Black); recorded so that slice refuses the calibration for other materials");
}

struct FitRequest {
  calibration::FitOptions fit;
  std::string rigid, rubbery;  // both empty without --materials
};

// --model, --floor-mpa and --materials checked; the last usage error found, or the request.
std::variant<FitRequest, std::string> readFitRequest(const po::variables_map& vm) {
  const std::string modelText = vm["model"].as<std::string>();
  const auto model = calibration::parseModel(modelText);
  const double floorMpa = vm["floor-mpa"].as<double>();
  std::string usageError;
  if (!model) usageError = "--model: expected pchip, lichtenecker or log-power, got '" + modelText + "'";
  else if (!std::isfinite(floorMpa) || !(floorMpa > 0)) usageError = "--floor-mpa: expected a modulus > 0 MPa";
  FitRequest r;
  if (vm.count("materials")) {
    try {
      const std::array<std::string, 2> pair = parseMaterialPair("--materials", vm["materials"].as<std::string>());
      r.rigid = pair[0], r.rubbery = pair[1];
    } catch (const BadValue& e) {
      usageError = e.what();
    }
  }
  if (!usageError.empty()) return usageError;
  r.fit = {*model, floorMpa};
  return r;
}

// The fit, with the materials recorded when --materials named them.
calibration::Calibration withMaterials(calibration::Calibration fit, const FitRequest& r) {
  if (r.rigid.empty()) return fit;
  calibration::FitRecord record = fit.record();
  record.rigidMaterial = r.rigid;
  record.rubberyMaterial = r.rubbery;
  return calibration::Calibration(fit.parameters(), fit.floorMpa(), std::move(record));
}

}  // namespace

int runCalibrate(const std::vector<std::string>& args) {
  po::options_description options("options");
  addCalibrateOptions(options);
  po::positional_options_description positional;
  positional.add("data", 1);
  po::variables_map vm;
  if (auto code = parseOptions("calibrate", options, positional, args, vm)) return *code;
  const std::variant<FitRequest, std::string> read = readFitRequest(vm);
  if (const auto* error = std::get_if<std::string>(&read)) return cli::usageError("calibrate", *error);
  const FitRequest& request = std::get<FitRequest>(read);

  commandLineAccepted();
  const std::string file = vm["data"].as<std::string>();
  const std::string output = vm.count("output") ? vm["output"].as<std::string>() : "";
  const std::string plot = vm.count("plot") ? vm["plot"].as<std::string>() : "";
  if (vm.count("output") && vm.count("plot") && output == plot)
    return cli::usageError("calibrate", "--output and --plot name the same file");
  // Existing outputs are replaced only when rodfab wrote them (a calibration file, a fit plot).
  if (vm.count("output") && !outputAllowed(output, {file}, {"calibration file", true, "", calibration::isCalibrationFile}))
    return kFailed;
  if (vm.count("plot") && !outputAllowed(plot, {file}, {"fit plot", true, "", calibration::isFitPlot})) return kFailed;
  calibration::DataSet data;
  try {
    data = calibration::readData(file);
  } catch (const calibration::DataError& e) {
    std::cerr << e.what() << '\n'
              << file << ": " << common::issueCountText(e.issues()) << "; nothing fitted\n";
    return kFailed;
  }
  const calibration::Calibration fit = withMaterials(calibration::fitCalibration(data, request.fit), request);
  if (const std::string& dither = fit.record().dither; !dither.empty() && !materials::isDitherMethod(dither)) {
    // A job's default ditherer comes from this field: a name no ditherer has would make every job fail.
    std::cerr << file << ": dither: unknown ditherer '" << dither << "', expected one of: " << materials::ditherMethodList()
              << "; nothing fitted\n";
    return kFailed;
  }
  printCalibrationFit(fit);
  if (vm.count("output")) {
    try {
      calibration::writeCalibration(fit, output);
    } catch (const calibration::CalibrationFileError& e) {  // the fit would not read back: the data's fault
      std::cerr << file << ": this data's fit cannot be used as a calibration: " << e.what() << "\nnothing was written\n";
      return kFailed;
    }
    std::printf("wrote:         %s\n", output.c_str());
  }
  if (vm.count("plot")) {
    calibration::writeFitPlot(fit, plot);
    std::printf("wrote:         %s\n", plot.c_str());
  }
  return kOk;
}

}  // namespace rodfab::cli
