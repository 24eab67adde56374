// The calibration file (`rodfab.calibration/1`, JSON): what a fit produced, for the slicer to load.
#pragma once

#include "calibration/model.hpp"

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <stdexcept>
#include <string>

namespace rodfab::calibration {

inline constexpr const char* kCalibrationFormat = "rodfab.calibration/1";

// what() is `FILE: JSON.PATH: what was expected`.
class CalibrationFileError : public std::runtime_error {
public:
  CalibrationFileError(const std::string& file, const std::string& path, const std::string& message);
};

nlohmann::ordered_json calibrationToJson(const Calibration& calibration);
// Checks every field, and that the stored floor fraction and maximum modulus agree with the model.
Calibration calibrationFromJson(const nlohmann::json& json, const std::string& sourceName);

// Written under a temporary name and renamed, so no reader sees half a file, and sealed as rodfab's
// (common::sealJsonObject). Throws CalibrationFileError, writing nothing, for a calibration that
// readCalibration would refuse (a fit whose quality figures are not numbers, a modulus beyond a float).
void writeCalibration(const Calibration& calibration, const std::filesystem::path& file);

// True when `file` is a regular file writeCalibration wrote and nobody has changed since (its seal
// matches): what `calibrate --output` may replace.
bool isCalibrationFile(const std::filesystem::path& file);
// With `sha256`, also the checksum of the bytes that were parsed (what a job records as its calibration).
Calibration readCalibration(const std::filesystem::path& file, std::string* sha256 = nullptr);

// The bundled default, fitted from the published 60 C figures: calibration/default-60C.json in
// rodfab's data folder (common/data_dir.hpp; installed from examples/calibration/). Throws
// common::DataDirError when it is missing.
std::filesystem::path defaultCalibrationPath();
Calibration loadDefaultCalibration();

}  // namespace rodfab::calibration
