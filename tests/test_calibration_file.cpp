// calibration/: calibration files (round trip, refusals naming file and field, the bundled default)
// and fit plots, checked by reading the files back and decoding the PNG with cairo.
#include "calibration/calibration.hpp"
#include "tests/calibration_fixtures.hpp"

#include <cairo.h>
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>

using namespace rodfab::calibration;
using namespace rodfab::calibration::testing;

TEST_CASE("a calibration file round-trips exactly", "[calibration][file]") {
  TempDir dir;
  for (Model model : {Model::Pchip, Model::Lichtenecker, Model::LogPower}) {
    const Calibration original = fitText(replicatedCsv(truthLogPower), model);
    const fs::path file = dir.path / (std::string(modelName(model)) + ".json");
    writeCalibration(original, file);
    CHECK_FALSE(fs::exists(file.string() + ".tmp"));
    CHECK(isCalibrationFile(file));  // sealed as rodfab's: what calibrate --output may replace
    const Calibration back = readCalibration(file);
    CHECK(back.model() == model);
    CHECK(back.parameters().fractions == original.parameters().fractions);
    CHECK(back.parameters().moduliMpa == original.parameters().moduliMpa);
    CHECK(back.parameters().exponent == original.parameters().exponent);
    CHECK(back.floorMpa() == original.floorMpa());
    CHECK(back.floorFraction() == original.floorFraction());
    CHECK(back.maxModulusMpa() == original.maxModulusMpa());
    CHECK(back.record().dataSha256 == original.record().dataSha256);
    CHECK(back.record().dataFile == "test.csv");
    CHECK(back.record().dither == "random");
    CHECK(back.record().temperatureC == original.record().temperatureC);
    REQUIRE(back.record().measurements.size() == 16);
    CHECK(back.record().measurements[5].modulusMpa == original.record().measurements[5].modulusMpa);
    CHECK(back.record().measurements[5].specimen == "s6");
    CHECK(back.record().quality.rmsLn == original.record().quality.rmsLn);
    CHECK(back.record().quality.leaveOneOutRmsLn == original.record().quality.leaveOneOutRmsLn);
    for (double f = 0; f <= 1; f += 0.01) CHECK(back.lnModulus(f) == original.lnModulus(f));
    // The file names its format, and the JSON carries the documented keys.
    std::ifstream in(file);
    const nlohmann::json j = nlohmann::json::parse(in);
    CHECK(j["format"] == "rodfab.calibration/1");
    CHECK(j["floor"]["modulus_mpa"] == 8.0);
  }
}

TEST_CASE("bad calibration files name the file and the field", "[calibration][file]") {
  const nlohmann::json good = nlohmann::json::parse(calibrationToJson(fitText(kPublished)).dump());
  const auto error = [](const nlohmann::json& j) -> std::string {
    try {
      calibrationFromJson(j, "cal.json");
    } catch (const CalibrationFileError& e) {
      return e.what();
    }
    return "no error";
  };
  CHECK(error(good) == "no error");
  auto j = good;
  j["format"] = "rodfab.calibration/9";
  CHECK_THAT(error(j), Catch::StartsWith("cal.json: format: expected \"rodfab.calibration/1\""));
  j = good;
  j["model"] = "spline";
  CHECK_THAT(error(j), Catch::StartsWith("cal.json: model: expected \"pchip\", \"lichtenecker\" or \"log-power\""));
  j = good;
  j["floor"]["vero_fraction"] = 0.31;
  CHECK_THAT(error(j), Catch::StartsWith("cal.json: floor.vero_fraction: the model gives Vero fraction 0.300000"));
  j = good;
  j["parameters"]["points"][1]["modulus_mpa"] = 0.4;
  CHECK_THAT(error(j), Catch::StartsWith("cal.json: parameters.points[1].modulus_mpa: node moduli must strictly increase"));
  j = good;
  j["parameters"]["points"][2]["vero_fraction"] = 0.9;
  CHECK_THAT(error(j), Catch::StartsWith("cal.json: parameters.points[2].vero_fraction: the last node must be at Vero fraction 1"));
  j = good;
  j["data"].erase("sha256");
  CHECK_THAT(error(j), Catch::StartsWith("cal.json: data.sha256: missing"));
  j = good;
  j["data"]["measurements"][0]["modulus_mpa"] = "soft";
  CHECK_THAT(error(j), Catch::StartsWith("cal.json: data.measurements[0].modulus_mpa: expected a modulus in MPa"));
  j = good;
  j["extra"] = 1;
  CHECK_THAT(error(j), Catch::StartsWith("cal.json: extra: unknown key"));
  j = good;
  j["floor"]["modulus_mpa"] = 500;
  CHECK_THAT(error(j), Catch::Contains("the floor (500 MPa) must lie"));
  // Material names: no control character (an escape sequence reached the terminal through slice), at
  // most 64 characters, as printer profiles name materials.
  j = good;
  j["materials"] = {{"rigid", "Vero\x1b[31mX"}, {"rubbery", "TangoBlackPlus"}};
  CHECK_THAT(error(j), Catch::StartsWith("cal.json: materials.rigid: expected a material name of at most 64 characters without control "
                                         "characters, got \"Vero\\u001b[31mX\""));
  j["materials"] = {{"rigid", "VeroWhitePlus"}, {"rubbery", std::string(65, 'T')}};
  CHECK_THAT(error(j), Catch::StartsWith("cal.json: materials.rubbery: expected a material name of at most 64 characters"));
  j["materials"] = {{"rigid", "VeroWhitePlus"}, {"rubbery", std::string(64, 'T')}};
  CHECK(error(j) == "no error");

  TempDir dir;
  std::ofstream(dir.path / "broken.json") << "{ \"format\": ";
  CHECK_THROWS_WITH(readCalibration(dir.path / "broken.json"), Catch::Contains("broken.json: malformed JSON at line 1"));
  std::ofstream(dir.path / "overflow.json") << "{ \"format\": 1e400 }";  // beyond a double: a file error too
  CHECK_THROWS_AS(readCalibration(dir.path / "overflow.json"), CalibrationFileError);
  CHECK_THROWS_WITH(readCalibration(dir.path / "overflow.json"), Catch::Contains("overflow.json: format: a number beyond the range of a double at line 1, column 13"));
  CHECK_THROWS_WITH(readCalibration(dir.path / "absent.json"), Catch::Contains("absent.json: cannot open"));
}

TEST_CASE("the bundled default calibration is what refitting the bundled data gives", "[calibration][file]") {
  const Calibration committed = loadDefaultCalibration();
  const Calibration refit = fitCalibration(readData(kBundledCsv), {committed.model(), committed.floorMpa()});
  CHECK(committed.record().dataSha256 == refit.record().dataSha256);
  CHECK(committed.model() == Model::Pchip);
  REQUIRE(committed.parameters().fractions.size() == refit.parameters().fractions.size());
  for (std::size_t i = 0; i < refit.parameters().fractions.size(); ++i) {
    CHECK(committed.parameters().fractions[i] == refit.parameters().fractions[i]);
    CHECK(committed.parameters().moduliMpa[i] == Approx(refit.parameters().moduliMpa[i]).epsilon(1e-14));
  }
  CHECK(committed.floorFraction() == Approx(refit.floorFraction()).margin(1e-12));
  CHECK(committed.maxModulusMpa() == Approx(refit.maxModulusMpa()).epsilon(1e-14));
  CHECK(committed.record().temperatureC == 60.0);
  CHECK(committed.record().quality.leaveOneOutRmsLn == Approx(*refit.record().quality.leaveOneOutRmsLn).epsilon(1e-12));
  CHECK(fs::path(committed.record().dataFile).filename() == "vero-tango-60C.csv");
}

TEST_CASE("the fit plot is a PNG that decodes and shows the curve and the floor", "[calibration][plot]") {
  TempDir dir;
  const fs::path png = dir.path / "fit.png";
  const Calibration c = fitText(replicatedCsv(truthLogPower));
  writeFitPlot(c, png);
  CHECK_FALSE(fs::exists(png.string() + ".tmp"));
  std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)> image(
      cairo_image_surface_create_from_png(png.c_str()), cairo_surface_destroy);
  REQUIRE(cairo_surface_status(image.get()) == CAIRO_STATUS_SUCCESS);
  const int width = cairo_image_surface_get_width(image.get()), height = cairo_image_surface_get_height(image.get());
  CHECK(width == 960);
  CHECK(height == 640);
  // Count the curve's blue and the floor's red (both saturated; the rest is grey, black or pale).
  const unsigned char* data = cairo_image_surface_get_data(image.get());
  const int stride = cairo_image_surface_get_stride(image.get());
  int blue = 0, red = 0, white = 0;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const unsigned char* p = data + y * stride + 4 * x;  // native-endian xRGB: B, G, R on little-endian
      const int b = p[0], g = p[1], r = p[2];
      blue += b > 150 && r < 80 && g < 130;
      red += r > 170 && g < 80 && b < 80;
      white += r == 255 && g == 255 && b == 255;
    }
  CHECK(blue > 800);   // ~850 px of curve, 2.5 px wide
  CHECK(red > 200);    // the dashed floor lines and the floor point
  CHECK(white > width * height / 3);

  // A failed write leaves nothing behind and names the file.
  CHECK_THROWS_WITH(writeFitPlot(c, dir.path / "no-such-dir" / "fit.png"), Catch::Contains("no-such-dir/fit.png"));
  CHECK_FALSE(fs::exists(dir.path / "no-such-dir"));
  CHECK_THROWS_WITH(writeCalibration(c, dir.path / "no-such-dir" / "c.json"), Catch::Contains("no-such-dir/c.json"));
}

TEST_CASE("a calibration the readers would refuse is never written, and an edited one is no longer rodfab's", "[calibration][file]") {
  TempDir dir;
  const Calibration good = fitText(replicatedCsv(truthLogPower), Model::LogPower);
  // A quality figure that is not a number (a fit of denormal fractions gave one) is written as null,
  // which slice refuses: writeCalibration refuses it first, naming the file and the field.
  FitRecord record = good.record();
  record.quality.rmsLn = std::numeric_limits<double>::quiet_NaN();
  const Calibration nan(good.parameters(), good.floorMpa(), record);
  CHECK_THROWS_WITH(writeCalibration(nan, dir.path / "nan.json"),
                    Catch::Contains("nan.json (not written)") && Catch::Contains("quality.rms_ln"));
  CHECK_FALSE(fs::exists(dir.path / "nan.json"));
  // A file rodfab wrote, then edited by hand, is not replaced by calibrate any more.
  writeCalibration(good, dir.path / "c.json");
  REQUIRE(isCalibrationFile(dir.path / "c.json"));
  std::ifstream in(dir.path / "c.json");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  text.replace(text.find("\"temperature_c\""), 1, " \"");
  std::ofstream(dir.path / "edited.json") << text;
  CHECK_NOTHROW(readCalibration(dir.path / "edited.json"));  // still a calibration
  CHECK_FALSE(isCalibrationFile(dir.path / "edited.json"));
}
