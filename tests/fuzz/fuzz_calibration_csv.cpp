// libFuzzer target: the calibration CSV reader must answer every input with a data set or a DataError,
// never crash, hang or throw anything else; a data set it accepts must hold only rows within the
// documented ranges and must be safe to fit (a FitError at most) and to query.
#include "calibration/data.hpp"
#include "calibration/fit.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  rodfab::calibration::DataSet set;
  try {
    set = rodfab::calibration::parseData(text, "fuzz.csv");
  } catch (const rodfab::calibration::DataError&) {
    return 0;
  }
  if (set.measurements.empty() || set.sha256.size() != 64) std::abort();
  for (const auto& m : set.measurements) {
    if (!(m.veroFraction >= 0.0 && m.veroFraction <= 1.0)) std::abort();
    if (!(m.modulusMpa > 0.0) || !std::isfinite(m.modulusMpa)) std::abort();
    if (m.temperatureC && !std::isfinite(*m.temperatureC)) std::abort();
    if (m.line <= 0) std::abort();
  }
  try {
    const auto calibration = rodfab::calibration::fitCalibration(set);
    for (const double e : {0.0, calibration.floorMpa(), calibration.minModulusMpa(), calibration.maxModulusMpa(),
                           set.measurements.front().modulusMpa}) {
      const auto result = calibration.fraction(e);
      if (!(result.fraction >= 0.0 && result.fraction <= 1.0)) std::abort();
    }
  } catch (const rodfab::calibration::FitError&) {
  }
  return 0;
}
