// Shared by the calibration tests (test_calibration.cpp, test_calibration_file.cpp): the bundled and
// published data, synthetic replicates of a known law, and a scratch directory.
#pragma once

#include "calibration/calibration.hpp"
#include "tests/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>

namespace rodfab::calibration::testing {

namespace fs = std::filesystem;

inline const fs::path kBundledCsv = fs::path(RODFAB_SOURCE_DIR) / "examples" / "calibration" / "vero-tango-60C.csv";

// The published 60 C figures without comments, for tests that do not need the bundled file.
inline const char* const kPublished =
    "vero_fraction,modulus_mpa\n"
    "0,0.5\n"
    "0.3,8\n"
    "1,190\n";

// Replicates at +-5 % (multiplicative) around a log-power law ln E = ln 0.5 + ln 380 f^0.7, so each
// fraction's geometric mean lies exactly on the law.
inline double truthLogPower(double f) { return std::exp(std::log(0.5) + std::log(380.0) * std::pow(f, 0.7)); }

inline std::string replicatedCsv(double (*law)(double)) {
  std::ostringstream csv;
  csv.precision(17);
  csv << "# synthetic replicates\nvero_fraction,modulus_mpa,temperature_c,specimen,dither\n";
  int n = 0;
  for (double f : {0.0, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0})
    for (double factor : {1.05, 1.0 / 1.05}) csv << f << ',' << law(f) * factor << ",60.2,s" << ++n << ",random\n";
  return csv.str();
}

inline Calibration fitText(const std::string& csv, Model model = Model::Pchip, double floorMpa = kDefaultFloorMpa) {
  return fitCalibration(parseData(csv, "test.csv"), {model, floorMpa});
}

struct TempDir : rodfab::test::TempDir {
  TempDir() : rodfab::test::TempDir("calibration") {}
};

}  // namespace rodfab::calibration::testing
