#include "calibration/calibration_file.hpp"

#include "common/data_dir.hpp"
#include "common/json_input.hpp"
#include "common/output_file.hpp"
#include "common/quoted_text.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

namespace rodfab::calibration {

using nlohmann::json;
using nlohmann::ordered_json;

namespace {

using common::describeJson;
using common::indexPath;
using common::memberPath;

class Reader {
public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& message) const {
    throw CalibrationFileError(file_, path, message);
  }

  void onlyKeys(const json& obj, const std::string& path, const std::set<std::string>& allowed) const {
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      if (!allowed.count(it.key())) fail(memberPath(path, it.key()), common::unknownKeyMessage(allowed));
    }
  }

  const json& object(const json& j, const std::string& path, const std::string& what) const {
    if (!j.is_object()) fail(path, "expected " + what + " (an object), got " + describeJson(j));
    return j;
  }

  const json& get(const json& obj, const std::string& path, const std::string& key, const std::string& what) const {
    auto it = obj.find(key);
    if (it == obj.end()) fail(memberPath(path, key), "missing; expected " + what);
    return *it;
  }

  double number(const json& j, const std::string& path, const std::string& what) const {
    if (!j.is_number()) fail(path, "expected " + what + ", got " + describeJson(j));
    return j.get<double>();
  }

  double positive(const json& j, const std::string& path, const std::string& what) const {
    const double v = number(j, path, what + " (a number > 0)");
    if (!(v > 0.0)) fail(path, "expected " + what + " > 0, got " + describeJson(j));
    return v;
  }

  double fraction(const json& j, const std::string& path) const {
    const double v = number(j, path, "a Vero fraction from 0 to 1");
    if (v < 0.0 || v > 1.0) fail(path, "expected a Vero fraction from 0 to 1, got " + describeJson(j));
    return v;
  }

  std::size_t count(const json& j, const std::string& path) const {
    if (!j.is_number_unsigned()) fail(path, "expected a count (an integer >= 0), got " + describeJson(j));
    return j.get<std::size_t>();
  }

  std::string string(const json& j, const std::string& path, const std::string& what) const {
    if (!j.is_string()) fail(path, "expected " + what + " (a string), got " + describeJson(j));
    return j.get<std::string>();
  }

  std::optional<double> optionalNumber(const json& obj, const std::string& path, const std::string& key, const std::string& what) const {
    auto it = obj.find(key);
    if (it == obj.end() || it->is_null()) return std::nullopt;
    return number(*it, memberPath(path, key), what);
  }

  std::string optionalString(const json& obj, const std::string& path, const std::string& key, const std::string& what) const {
    auto it = obj.find(key);
    if (it == obj.end() || it->is_null()) return {};
    return string(*it, memberPath(path, key), what);
  }

  const std::string& file() const { return file_; }

private:
  std::string file_;
};

bool agrees(double stored, double computed, double tolerance) {
  return std::abs(stored - computed) <= tolerance * std::max(1.0, std::abs(computed));
}

ordered_json measurementToJson(const Measurement& m) {
  ordered_json j{{"line", m.line}, {"vero_fraction", m.veroFraction}, {"modulus_mpa", m.modulusMpa}};
  if (m.temperatureC) j["temperature_c"] = *m.temperatureC;
  if (!m.specimen.empty()) j["specimen"] = m.specimen;
  if (!m.dither.empty()) j["dither"] = m.dither;
  if (!m.date.empty()) j["date"] = m.date;
  return j;
}

// The parameters of a pchip model: its nodes, from fraction 0 to 1, strictly increasing.
void readPchipNodes(const Reader& in, const json& params, ModelParameters& p) {
  in.onlyKeys(params, "parameters", {"points"});
  const json& points = in.get(params, "parameters", "points", "the pchip nodes");
  if (!points.is_array() || points.size() < 2)
    in.fail("parameters.points", "expected an array of at least two {vero_fraction, modulus_mpa} nodes, got " + describeJson(points));
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::string path = indexPath("parameters.points", i);
    in.object(points[i], path, "a node {vero_fraction, modulus_mpa}");
    in.onlyKeys(points[i], path, {"vero_fraction", "modulus_mpa"});
    const double f = in.fraction(in.get(points[i], path, "vero_fraction", "a Vero fraction"), memberPath(path, "vero_fraction"));
    const double e = in.positive(in.get(points[i], path, "modulus_mpa", "a modulus in MPa"), memberPath(path, "modulus_mpa"), "a modulus in MPa");
    if (i == 0 && f != 0.0) in.fail(memberPath(path, "vero_fraction"), "the first node must be at Vero fraction 0, got " + describeJson(points[i]["vero_fraction"]));
    if (i + 1 == points.size() && f != 1.0) in.fail(memberPath(path, "vero_fraction"), "the last node must be at Vero fraction 1, got " + describeJson(points[i]["vero_fraction"]));
    if (i > 0 && !(f > p.fractions.back())) in.fail(memberPath(path, "vero_fraction"), "node fractions must strictly increase");
    if (i > 0 && !(e > p.moduliMpa.back())) in.fail(memberPath(path, "modulus_mpa"), "node moduli must strictly increase with the fraction");
    p.fractions.push_back(f);
    p.moduliMpa.push_back(e);
  }
}

// The parameters of the Lichtenecker and log-power models: the end moduli and the exponent.
void readPowerLaw(const Reader& in, const json& params, ModelParameters& p) {
  in.onlyKeys(params, "parameters", {"tango_modulus_mpa", "vero_modulus_mpa", "exponent"});
  p.tangoModulusMpa = in.positive(in.get(params, "parameters", "tango_modulus_mpa", "the modulus at 0 % Vero in MPa"),
                                  "parameters.tango_modulus_mpa", "a modulus in MPa");
  p.veroModulusMpa = in.positive(in.get(params, "parameters", "vero_modulus_mpa", "the modulus at 100 % Vero in MPa"),
                                 "parameters.vero_modulus_mpa", "a modulus in MPa");
  if (!(p.veroModulusMpa > p.tangoModulusMpa))
    in.fail("parameters.vero_modulus_mpa", "expected more than tango_modulus_mpa (" + describeJson(params["tango_modulus_mpa"]) + ")");
  const json& exponent = in.get(params, "parameters", "exponent", "the fitted exponent");
  p.exponent = p.model == Model::LogPower ? in.positive(exponent, "parameters.exponent", "a log-power exponent")
                                          : in.number(exponent, "parameters.exponent", "a Lichtenecker exponent (a number)");
}

ModelParameters readParameters(const Reader& in, const json& j, Model model) {
  ModelParameters p;
  p.model = model;
  const json& params = in.object(in.get(j, "", "parameters", "the model parameters"), "parameters", "the model parameters");
  if (p.model == Model::Pchip) readPchipNodes(in, params, p);
  else readPowerLaw(in, params, p);
  return p;
}

// Optional (files written before it existed have none): the materials the coupons were printed in.
void readMaterials(const Reader& in, const json& j, FitRecord& r) {
  const json& mat = in.object(j["materials"], "materials", "{rigid, rubbery} material names or null");
  in.onlyKeys(mat, "materials", {"rigid", "rubbery"});
  r.rigidMaterial = in.string(in.get(mat, "materials", "rigid", "the rigid material's name"), "materials.rigid", "a material name");
  r.rubberyMaterial = in.string(in.get(mat, "materials", "rubbery", "the rubbery material's name"), "materials.rubbery", "a material name");
  if (r.rigidMaterial.empty() || r.rubberyMaterial.empty()) in.fail("materials", "expected two non-empty material names");
  // Named as printer profiles name materials (at most 64 characters; they become file names there), so
  // that no control character or escape sequence reaches a terminal through slice's messages.
  for (const auto& [key, name] : {std::pair{"rigid", &r.rigidMaterial}, std::pair{"rubbery", &r.rubberyMaterial}})
    if (name->size() > 64 || common::holdsControlCharacters(*name))
      in.fail(std::string("materials.") + key, "expected a material name of at most 64 characters without control characters, got " +
                                                   describeJson(json(*name)));
}

void readMeasurements(const Reader& in, const json& rows, FitRecord& r) {
  if (rows.size() > kMaxMeasurements)
    in.fail("data.measurements", "expected at most " + std::to_string(kMaxMeasurements) + " measurements, got " + std::to_string(rows.size()));
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const std::string path = indexPath("data.measurements", i);
    in.object(rows[i], path, "a measurement");
    in.onlyKeys(rows[i], path, {"line", "vero_fraction", "modulus_mpa", "temperature_c", "specimen", "dither", "date"});
    Measurement m;
    m.line = static_cast<int>(in.count(in.get(rows[i], path, "line", "the CSV line number"), memberPath(path, "line")));
    m.veroFraction = in.fraction(in.get(rows[i], path, "vero_fraction", "a Vero fraction"), memberPath(path, "vero_fraction"));
    m.modulusMpa = in.positive(in.get(rows[i], path, "modulus_mpa", "a modulus in MPa"), memberPath(path, "modulus_mpa"), "a modulus in MPa");
    m.temperatureC = in.optionalNumber(rows[i], path, "temperature_c", "a temperature in degrees Celsius");
    m.specimen = in.optionalString(rows[i], path, "specimen", "the specimen name");
    m.dither = in.optionalString(rows[i], path, "dither", "the ditherer's name");
    m.date = in.optionalString(rows[i], path, "date", "the date");
    r.measurements.push_back(std::move(m));
  }
}

void readQuality(const Reader& in, const json& quality, FitQuality& q) {
  in.onlyKeys(quality, "quality", {"measurements", "fractions", "rms_ln", "r2_ln", "max_relative_error", "leave_one_out_rms_ln"});
  q.measurements = in.count(in.get(quality, "quality", "measurements", "the number of measurements"), "quality.measurements");
  q.fractions = in.count(in.get(quality, "quality", "fractions", "the number of distinct fractions"), "quality.fractions");
  q.rmsLn = in.number(in.get(quality, "quality", "rms_ln", "the RMS error in ln E"), "quality.rms_ln", "a number");
  q.r2Ln = in.number(in.get(quality, "quality", "r2_ln", "R^2 in ln E"), "quality.r2_ln", "a number");
  q.maxRelativeError = in.number(in.get(quality, "quality", "max_relative_error", "the max relative error"), "quality.max_relative_error", "a number");
  q.leaveOneOutRmsLn = in.optionalNumber(quality, "quality", "leave_one_out_rms_ln", "the leave-one-out RMS error in ln E or null");
}

// The record of the fit: temperature, dither, materials, the data fitted and the fit's quality.
FitRecord readRecord(const Reader& in, const json& j) {
  FitRecord r;
  r.temperatureC = in.optionalNumber(j, "", "temperature_c", "a temperature in degrees Celsius or null");
  r.dither = in.optionalString(j, "", "dither", "the ditherer's name or null");
  if (j.contains("materials") && !j["materials"].is_null()) readMaterials(in, j, r);
  const json& data = in.object(in.get(j, "", "data", "{file, sha256, measurements}"), "data", "the fitted data");
  in.onlyKeys(data, "data", {"file", "sha256", "measurements"});
  r.dataFile = in.string(in.get(data, "data", "file", "the data file name"), "data.file", "the data file name");
  r.dataSha256 = in.string(in.get(data, "data", "sha256", "the SHA-256 of the data file"), "data.sha256", "64 hex digits");
  if (r.dataSha256.size() != 64 || r.dataSha256.find_first_not_of("0123456789abcdef") != std::string::npos)
    in.fail("data.sha256", "expected 64 lowercase hex digits, got " + describeJson(data["sha256"]));
  const json& rows = in.get(data, "data", "measurements", "the measurements fitted");
  if (!rows.is_array()) in.fail("data.measurements", "expected an array of measurements, got " + describeJson(rows));
  readMeasurements(in, rows, r);
  const json& quality = in.object(in.get(j, "", "quality", "the fit quality"), "quality", "the fit quality");
  readQuality(in, quality, r.quality);
  return r;
}

}  // namespace

CalibrationFileError::CalibrationFileError(const std::string& file, const std::string& path, const std::string& message)
    : std::runtime_error(file + ": " + (path.empty() ? "" : path + ": ") + message) {}

ordered_json calibrationToJson(const Calibration& c) {
  const ModelParameters& p = c.parameters();
  const FitRecord& r = c.record();
  ordered_json parameters;
  if (p.model == Model::Pchip) {
    parameters["points"] = ordered_json::array();
    for (std::size_t i = 0; i < p.fractions.size(); ++i)
      parameters["points"].push_back({{"vero_fraction", p.fractions[i]}, {"modulus_mpa", p.moduliMpa[i]}});
  } else {
    parameters = {{"tango_modulus_mpa", p.tangoModulusMpa}, {"vero_modulus_mpa", p.veroModulusMpa}, {"exponent", p.exponent}};
  }
  ordered_json measurements = ordered_json::array();
  for (const Measurement& m : r.measurements) measurements.push_back(measurementToJson(m));
  const FitQuality& q = r.quality;
  return ordered_json{
      {"format", kCalibrationFormat},
      {"model", std::string(modelName(p.model))},
      {"parameters", parameters},
      {"floor", {{"modulus_mpa", c.floorMpa()}, {"vero_fraction", c.floorFraction()}}},
      {"max_modulus_mpa", c.maxModulusMpa()},
      {"temperature_c", r.temperatureC ? ordered_json(*r.temperatureC) : ordered_json()},
      {"dither", r.dither.empty() ? ordered_json() : ordered_json(r.dither)},
      {"materials", r.rigidMaterial.empty() ? ordered_json()
                                            : ordered_json{{"rigid", r.rigidMaterial}, {"rubbery", r.rubberyMaterial}}},
      {"data", {{"file", r.dataFile}, {"sha256", r.dataSha256}, {"measurements", measurements}}},
      {"quality",
       {{"measurements", q.measurements},
        {"fractions", q.fractions},
        {"rms_ln", q.rmsLn},
        {"r2_ln", q.r2Ln},
        {"max_relative_error", q.maxRelativeError},
        {"leave_one_out_rms_ln", q.leaveOneOutRmsLn ? ordered_json(*q.leaveOneOutRmsLn) : ordered_json()}}}};
}

Calibration calibrationFromJson(const json& j, const std::string& sourceName) {
  const Reader in(sourceName);
  in.object(j, "", "a calibration");
  in.onlyKeys(j, "", {common::kWrittenByKey, "format", "model", "parameters", "floor", "max_modulus_mpa", "temperature_c", "dither",
                      "materials", "data", "quality"});
  if (j.contains(common::kWrittenByKey)) in.string(j[common::kWrittenByKey], common::kWrittenByKey, "rodfab's seal");  // read as text
  const std::string format = in.string(in.get(j, "", "format", std::string("\"") + kCalibrationFormat + "\""), "format", "the format tag");
  if (format != kCalibrationFormat) in.fail("format", std::string("expected \"") + kCalibrationFormat + "\", got " + describeJson(j["format"]));
  const std::string modelText = in.string(in.get(j, "", "model", "the model name"), "model", "the model name");
  const auto model = parseModel(modelText);
  if (!model) in.fail("model", "expected \"pchip\", \"lichtenecker\" or \"log-power\", got " + describeJson(j["model"]));

  ModelParameters p = readParameters(in, j, *model);

  const json& floor = in.object(in.get(j, "", "floor", "{modulus_mpa, vero_fraction}"), "floor", "the floor");
  in.onlyKeys(floor, "floor", {"modulus_mpa", "vero_fraction"});
  const double floorMpa = in.positive(in.get(floor, "floor", "modulus_mpa", "the floor modulus in MPa"), "floor.modulus_mpa", "a modulus in MPa");
  const double floorFraction = in.fraction(in.get(floor, "floor", "vero_fraction", "the floor's Vero fraction"), "floor.vero_fraction");
  const double maxModulus = in.positive(in.get(j, "", "max_modulus_mpa", "the modulus at 100 % Vero in MPa"), "max_modulus_mpa", "a modulus in MPa");

  FitRecord r = readRecord(in, j);

  try {
    Calibration c(std::move(p), floorMpa, std::move(r));
    // A hand-edited parameter that no longer matches its derived values is caught here, not at print time.
    if (!agrees(floorFraction, c.floorFraction(), 1e-9))
      in.fail("floor.vero_fraction", "the model gives Vero fraction " + std::to_string(c.floorFraction()) + " for the floor, the file says " +
                                         describeJson(floor["vero_fraction"]));
    if (!(c.maxModulusMpa() < double(std::numeric_limits<float>::max())))  // a job's moduli are floats
      in.fail("max_modulus_mpa", "expected below the largest float, 3.4e38 MPa, got " + describeJson(j["max_modulus_mpa"]));
    if (!agrees(maxModulus, c.maxModulusMpa(), 1e-9))
      in.fail("max_modulus_mpa", "the model gives " + std::to_string(c.maxModulusMpa()) + " MPa at 100 % Vero, the file says " +
                                     describeJson(j["max_modulus_mpa"]));
    return c;
  } catch (const std::invalid_argument& e) {
    in.fail("", e.what());
  }
}

void writeCalibration(const Calibration& calibration, const std::filesystem::path& file) {
  const std::string text = calibrationToJson(calibration).dump(2) + "\n";  // "{\n" and the members
  // Read back as slice and optimize will: a fit they would refuse (a NaN quality figure, a modulus
  // beyond a float) is never written.
  calibrationFromJson(json::parse(text), file.string() + " (not written)");
  common::writeFileAtomically(file, common::sealJsonObject(std::string_view(text).substr(2)));
}

bool isCalibrationFile(const std::filesystem::path& file) {
  return common::fileStartsWith(file, "{", std::string("\"") + kCalibrationFormat + "\"", 256) && common::isSealedJsonObject(file);
}

Calibration readCalibration(const std::filesystem::path& file, std::string* sha256) {
  json j;
  try {
    const std::string text = common::readBoundedFile(file.string());
    if (sha256) *sha256 = sha256Hex(text);
    j = common::parseJsonStrict(text);
  } catch (const common::JsonInputError& e) {
    throw CalibrationFileError(file.string(), e.path, e.message);
  } catch (const json::exception& e) {  // out_of_range for a number too large (1e400)
    throw CalibrationFileError(file.string(), "", "not valid JSON: " + common::printableJsonError(e.what()));
  }
  return calibrationFromJson(j, file.string());
}

std::filesystem::path defaultCalibrationPath() {
  return common::dataFile("calibration/default-60C.json");
}

Calibration loadDefaultCalibration() { return readCalibration(defaultCalibrationPath()); }

}  // namespace rodfab::calibration
