// printer_profiles/: profiles (the bundled one, bad and hostile ones, refused naming the file and the
// JSON path), the 1-bit bitmap codecs and the job layout on the tray. Jobs written and decoded back:
// tests/test_printer_jobs.cpp.
#include "printer_profiles/printer_profiles.hpp"
#include "tests/printer_profiles_fixture.hpp"

#include "printer_profiles/deflate.hpp"  // internal: zipCrc32, deflateBytes

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <functional>
#include <random>
#include <stdexcept>
#include <utility>
#include <string>
#include <vector>

using namespace rodfab::printer_profiles;
namespace fs = std::filesystem;
using nlohmann::json;
using rodfab::test::connex3;
using rodfab::test::readAll;
using rodfab::test::scratch;
using rodfab::test::writeAll;

// ------------------------------------------------------------------------------------------ profiles

TEST_CASE("The bundled Connex3 profile loads with the printer's numbers", "[profile]") {
  const Profile& p = connex3();
  CHECK(p.name == "stratasys-objet500-connex3");
  CHECK(p.xDpi == 600);
  CHECK(p.yDpi == 300);
  CHECK(p.voxelSizeMm[0] == Approx(0.0423));
  CHECK(p.voxelSizeMm[1] == Approx(0.0846));
  CHECK(p.voxelSizeMm[2] == Approx(0.030));
  CHECK(p.trayMm == std::array<double, 3>{490, 390, 200});
  CHECK(p.modelMaterialSlots == 3);
  CHECK(p.material(MaterialRole::Rigid).name == "VeroWhitePlus");
  CHECK(p.material(MaterialRole::Rubbery).name == "TangoBlackPlus");
  CHECK(p.material(MaterialRole::Support).name == "FullCure705");
  CHECK(p.columnAlignment == 32);
  CHECK(p.supportPolicy == SupportPolicy::Printer);
  CHECK(p.layerFileName(p.material(MaterialRole::Rigid), 7, ImageFormat::Bmp) == "VeroWhitePlus_0007.bmp");
  CHECK(p.layerFileName(p.material(MaterialRole::Rigid), 12345, ImageFormat::Png) == "VeroWhitePlus_12345.png");
  CHECK(bundledProfileNames() == std::vector<std::string>{"stratasys-j750-j850", "stratasys-objet500-connex3"});
  CHECK(p.jobFormat == JobFormat::BitmapStacks);
  CHECK(p.printModes.empty());
}

TEST_CASE("Bad profiles are refused naming the file, the field and what was expected", "[profile]") {
  json doc = json::parse(readAll(bundledProfileDir() / "stratasys-objet500-connex3.json"));
  const auto issuesOf = [](const json& d) {
    try {
      parseProfile(d.dump(), "bad.json");
    } catch (const ProfileError& e) {
      CHECK(e.file() == "bad.json");
      CHECK(std::string(e.what()).starts_with("bad.json: "));
      return std::string(e.what());
    }
    FAIL("expected a ProfileError");
    return std::string();
  };
  SECTION("x and y swapped") {
    doc["resolution"]["voxel_size_mm"] = {0.0846, 0.0423, 0.03};
    const std::string what = issuesOf(doc);
    CHECK(what.find("resolution.voxel_size_mm[0]") != std::string::npos);
    CHECK(what.find("swapped") != std::string::npos);
  }
  SECTION("dpi swapped") {
    doc["resolution"]["x_dpi"] = 300;
    doc["resolution"]["y_dpi"] = 600;
    CHECK(issuesOf(doc).find("x_dpi = 300") != std::string::npos);
  }
  SECTION("no rubbery material, negative density") {
    doc["materials"].erase(1);
    doc["materials"][0]["density_g_per_ml"] = -1;
    const std::string what = issuesOf(doc);
    CHECK(what.find("role \"rubbery\", found 0") != std::string::npos);
    CHECK(what.find("materials[0].density_g_per_ml") != std::string::npos);
  }
  SECTION("bit depth and support policy") {
    doc["image"]["bit_depth"] = 8;
    doc["support"]["policy"] = "sometimes";
    const std::string what = issuesOf(doc);
    CHECK(what.find("image.bit_depth: expected 1") != std::string::npos);
    CHECK(what.find("support.policy") != std::string::npos);
  }
  SECTION("strings with control characters (they reach the terminal, summaries and reports)") {
    doc["printer"] = "Objet\x1b[2J\x1b]0;pwned\x07";
    doc["image"]["row_order"] = std::string("top\xc2\x9b" "2J");  // a C1 control (CSI) in UTF-8
    const std::string what = issuesOf(doc);
    CHECK_THAT(what, Catch::Contains("printer: expected a non-empty string of at most") && Catch::Contains("without control characters"));
    CHECK_THAT(what, Catch::Contains("image.row_order: expected a non-empty string"));
    CHECK(what.find('\x1b') == std::string::npos);
  }
  SECTION("not JSON") { CHECK(issuesOf(json("{")).find("") != std::string::npos); }
  SECTION("unknown bundled name lists the bundled ones") {
    try {
      loadProfile("objet-9000");
      FAIL("expected a ProfileError");
    } catch (const ProfileError& e) {
      CHECK(std::string(e.what()).find("stratasys-objet500-connex3") != std::string::npos);
    }
  }
}

// ------------------------------------------------------------------------------------------ bitmaps

TEST_CASE("1-bit BMP and PNG round-trip with their resolution", "[bitmap]") {
  Bitmap b(96, 5);
  std::mt19937 rng(3);
  for (int r = 0; r < 5; ++r)
    for (int c = 0; c < 96; ++c) b.set(c, r, rng() % 3 == 0);
  b.set(0, 0);  // top-left corner pixel: catches a row-order mistake
  const Bytes bmp = encodeBmp(b, 600, 300);
  CHECK(bmp.size() == 62 + 12 * 5);
  const DecodedBitmap fromBmp = decodeBmp(bmp);
  CHECK(fromBmp.bitmap == b);
  CHECK(fromBmp.bitDepth == 1);
  CHECK(fromBmp.xPixelsPerMetre == 23622);
  CHECK(fromBmp.yPixelsPerMetre == 11811);
  // BMP rows are stored bottom-up: the top-left pixel is the first bit of the last stored row.
  CHECK((bmp[62 + 12 * 4] & 0x80) != 0);

  const DecodedBitmap fromPng = decodePng1(encodePng1(b, 600, 300));
  CHECK(fromPng.bitmap == b);
  CHECK(fromPng.bitDepth == 1);
  CHECK(fromPng.xPixelsPerMetre == 23622);
  CHECK(fromPng.yPixelsPerMetre == 11811);

  Bytes truncated(bmp.begin(), bmp.end() - 7);
  CHECK_THROWS_WITH(decodeBmp(truncated), Catch::Contains("truncated"));
  Bytes eightBit = bmp;
  eightBit[28] = 8;
  CHECK_THROWS_WITH(decodeBmp(eightBit), Catch::Contains("expected 1"));
  const Bytes rgb = encodePngRgb(RgbImage(4, 4, 10, 20, 30));
  CHECK_THROWS_WITH(decodePng1(rgb), Catch::Contains("expected 0 (grayscale)"));
  Bytes png = encodePng1(b, 600, 300);
  png.resize(png.size() / 2);
  CHECK_THROWS_AS(decodePng1(png), ImageError);
}

TEST_CASE("A PNG's declared size is checked before its bitmap is allocated", "[bitmap][png]") {
  // The header of a small 1-bit PNG made to declare w x h pixels (its IHDR's CRC made again): a
  // 700-byte file declaring 10^6 x 24,000 took inspect to 3 GB before libpng found its data short.
  const Bytes small = encodePng1(Bitmap(37, 13), 600, 300);
  const auto declaring = [&](std::uint32_t w, std::uint32_t h) {
    Bytes png = small;
    for (int i = 0; i < 4; ++i) {
      png[16 + i] = static_cast<std::uint8_t>(w >> (24 - 8 * i));
      png[20 + i] = static_cast<std::uint8_t>(h >> (24 - 8 * i));
    }
    const std::uint32_t crc = zipCrc32(std::span<const std::uint8_t>(png.data() + 12, 17));  // "IHDR" and its 13 bytes
    for (int i = 0; i < 4; ++i) png[29 + i] = static_cast<std::uint8_t>(crc >> (24 - 8 * i));
    return png;
  };
  CHECK_THROWS_WITH(decodePng1(declaring(1000000, 24000)), Catch::Contains("PNG declares 1000000 x 24000 pixels, more than its") &&
                                                                Catch::Contains("bytes can hold"));
  CHECK_THROWS_WITH(decodePng1(declaring(38, 13), 37 * 13), Catch::Contains("PNG declares 38 x 13 pixels, more than expected"));
  // Within both bounds the header is read as before: the rows then run short, which libpng reports.
  CHECK_THROWS_AS(decodePng1(declaring(37, 14), 37 * 14), ImageError);
  CHECK(decodePng1(declaring(37, 13), 37 * 13).bitmap.width() == 37);
}

// libpng inflates whatever image data follows the last row, to discard it: a GCVF whose layers' data went
// on to inflate to a GB of zeros each kept inspect busy for minutes.
TEST_CASE("A PNG whose image data goes on past its rows is refused without inflating the rest", "[bitmap][png]") {
  constexpr int kWidth = 64, kHeight = 8;
  const auto rowOf = [](int, std::uint8_t* out) { std::memset(out, 0, kWidth * 4); };
  const Bytes sound = encodePngRgba(kWidth, kHeight, 600, 300, rowOf);
  const auto chunk = [](const char* type, const Bytes& data) {
    Bytes c(4 + 4 + data.size() + 4);
    for (int i = 0; i < 4; ++i) c[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(data.size() >> (24 - 8 * i));
    std::memcpy(c.data() + 4, type, 4);
    std::copy(data.begin(), data.end(), c.begin() + 8);
    const std::uint32_t crc = zipCrc32(std::span<const std::uint8_t>(c.data() + 4, 4 + data.size()));
    for (int i = 0; i < 4; ++i) c[8 + data.size() + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(crc >> (24 - 8 * i));
    return c;
  };
  const auto withImageData = [&](std::size_t rawBytes) {  // the rows (filter 0, zeros), then zeros to rawBytes
    const Bytes idat = deflateBytes(Bytes(rawBytes, 0), 0, DeflateWrapper::Zlib);
    Bytes png(sound.begin(), sound.begin() + 33);  // signature and IHDR
    for (const Bytes& c : {chunk("IDAT", idat), chunk("IEND", {})}) png.insert(png.end(), c.begin(), c.end());
    return png;
  };
  const std::size_t rows = kHeight * (1 + kWidth * 4);
  int decoded = 0;
  const auto decode = [&](const Bytes& png) { return decodePngRgba(png, kWidth * kHeight, [](const RgbaHeader&) {}, [&](int, const std::uint8_t*) { ++decoded; }); };
  CHECK(decode(withImageData(rows)).width == kWidth);
  CHECK(decoded == kHeight);
  CHECK_THROWS_WITH(decode(withImageData(rows + (std::size_t{256} << 20))), Catch::Contains("PNG is damaged: more than 32 KiB of data follow the image's rows"));
}

TEST_CASE("RGB PNGs (the previews) decode to the pixels given, whole or fed in row batches", "[bitmap][png]") {
  // 1 x 1; 700 x 400 (840 kB of rows: one batch); 1500 x 900 (4 MB: the streamed batches, as a preview).
  for (const auto& [width, height] : {std::pair{1, 1}, std::pair{700, 400}, std::pair{1500, 900}}) {
    RgbImage image(width, height, 0, 0, 0);
    std::mt19937 rng(static_cast<unsigned>(width * 7 + height));
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) {
        std::uint8_t* p = image.at(x, y);
        const bool noisy = (x / 50 + y / 50) % 3 == 0;  // flat areas and noise, like captions on a view
        for (int c = 0; c < 3; ++c) p[c] = noisy ? static_cast<std::uint8_t>(rng()) : static_cast<std::uint8_t>(40 * c + x / 100);
      }
    const Bytes png = encodePngRgb(image);
    const RgbImage back = decodePngRgb(png);  // libpng, with zlib: not the encoder's igzip
    CHECK(back.width == width);
    CHECK(back.height == height);
    CHECK(back.pixels == image.pixels);
    // The row-callback form is the same file.
    const std::size_t stride = static_cast<std::size_t>(width) * 3;
    CHECK(encodePngRgb(width, height, [&](int r, std::uint8_t* out) {
            std::copy_n(image.pixels.data() + static_cast<std::size_t>(r) * stride, stride, out);
          }) == png);
  }
  Bytes cut = encodePngRgb(RgbImage(300, 300, 1, 2, 3));
  cut.resize(cut.size() - 20);  // IEND and the end of the image data
  CHECK_THROWS_AS(decodePngRgb(cut), ImageError);
}

TEST_CASE("A bitmap held in its BMP file reads and writes as any bitmap, and its memory is encodeBmp's file", "[bitmap]") {
  // Rows padded to 32-bit words and not (widths 1, 96 and 1000 pad, 2080 does not), one row and many.
  for (const auto& [width, height] : {std::pair{1, 1}, std::pair{96, 5}, std::pair{1000, 300}, std::pair{2080, 7}}) {
    Bitmap plain(width, height);
    Bitmap inFile = Bitmap::inBmpFile(width, height, 600, 300);
    CHECK(inFile == plain);
    CHECK(inFile.bmpFile().size() == encodeBmp(plain, 600, 300).size());
    CHECK(plain.bmpFile().empty());
    std::mt19937 rng(static_cast<unsigned>(width));
    for (int r = 0; r < height; ++r)
      for (int c = 0; c < width; c += 1 + static_cast<int>(rng() % 5)) {
        plain.set(c, r);
        inFile.row(r)[c / 8] = static_cast<std::uint8_t>(inFile.row(r)[c / 8] | (0x80u >> (c % 8)));  // as the rasterizer writes
      }
    CHECK(inFile == plain);
    CHECK(inFile.count() == plain.count());
    const Bytes file(inFile.bmpFile().begin(), inFile.bmpFile().end());
    CHECK(file == encodeBmp(plain, 600, 300));                // the same file, headers and padding included
    CHECK(decodeBmp(inFile.bmpFile()).bitmap == plain);       // read back by the decoder, independently of the layout
    CHECK(encodeBmp(inFile, 600, 300) == file);               // encodeBmp reads either layout
    CHECK(encodePng1(inFile, 600, 300) == encodePng1(plain, 600, 300));
    plain.set(0, height - 1, false);
    CHECK((inFile == plain) == !inFile.get(0, height - 1));  // a pixel apart: unequal (unless it was clear)
    inFile.clear();
    CHECK(inFile.count() == 0);
    CHECK(inFile == Bitmap(width, height));
    CHECK((Bytes(inFile.bmpFile().begin(), inFile.bmpFile().end()) == encodeBmp(Bitmap(width, height), 600, 300)));  // headers kept
  }
  CHECK_THROWS_AS(Bitmap::inBmpFile(0, 4, 600, 300), std::invalid_argument);
  CHECK_THROWS_AS(Bitmap::inBmpFile(4, -1, 600, 300), std::invalid_argument);
}

// ------------------------------------------------------------------------------------------ layout

TEST_CASE("The image frame covers the padded part, aligned, with row 0 the largest y", "[layout]") {
  const openvdb::CoordBBox part({5, -7, 3}, {46, 8, 26});
  const JobGeometry g = planJob(connex3(), part);
  CHECK(g.width % 32 == 0);
  CHECK(g.firstColumnI % 8 == 0);
  CHECK(g.column(part.min().x()) >= 32);
  CHECK(g.column(part.max().x()) < g.width - 32 + 32);
  CHECK(g.row(part.max().y()) == 16);
  CHECK(g.row(part.min().y()) == g.height - 1 - 16);
  CHECK(g.layer(3) == 0);
  CHECK(g.layers == 24);
}

TEST_CASE("An oversize design is refused with its overhang in millimetres", "[layout]") {
  // 12000 columns of 0.0423 mm = 507.6 mm: 17.6 mm more than the 490 mm tray.
  const openvdb::CoordBBox part({0, 0, 0}, {11999, 100, 10});
  try {
    planJob(connex3(), part);
    FAIL("expected a TrayFitError");
  } catch (const TrayFitError& e) {
    CHECK(e.overhangMm()[0] == Approx(12000 * 0.0423 - 490));
    CHECK(e.overhangMm()[1] == 0.0);
    CHECK(std::string(e.what()).find("by 17.600 mm along x") != std::string::npos);
  }
  CHECK_THROWS_WITH(planJob(connex3(), openvdb::CoordBBox({0, 0, 0}, {10, 10, 6700})), Catch::Contains("along z"));
}

// ------------------------------------------------------------------------------------------ jobs
// ------------------------------------------------------------------------------ hostile profiles

namespace {

json bundledProfileJson() { return json::parse(readAll(bundledProfileDir() / "stratasys-objet500-connex3.json")); }

// The issues a profile text is refused with (FAIL when it is accepted).
std::vector<ProfileIssue> refusalOf(const std::string& text) {
  try {
    parseProfile(text, "hostile.json");
  } catch (const ProfileError& e) {
    CHECK(std::string(e.what()).starts_with("hostile.json: "));
    return e.issues();
  }
  FAIL("expected a ProfileError for " << text.substr(0, 200));
  return {};
}

// The one issue found at `path`, its message containing `words`.
void refusedAt(const json& doc, const std::string& path, const std::string& words) {
  const std::vector<ProfileIssue> issues = refusalOf(doc.dump());
  std::string all;
  for (const ProfileIssue& i : issues) all += "\n  " + i.path + ": " + i.message;
  INFO("issues:" << all);
  const auto at = std::find_if(issues.begin(), issues.end(), [&](const ProfileIssue& i) { return i.path == path; });
  REQUIRE(at != issues.end());
  CHECK_THAT(at->message, Catch::Contains(words));
}

}  // namespace

TEST_CASE("Profile names must be portable file names, unique without regard to case", "[profile][hostile]") {
  for (const char* bad : {"..\\evil.txt", "C:evil.txt", "a/b.txt", "CON", "con.txt", "LPT1.bmp", ".hidden", "-rf",
                          "build.", "build txt", "b\xc3\xa9t.txt", "tab\there", ""}) {
    json doc = bundledProfileJson();
    doc["build_file"]["name"] = bad;
    INFO("build file name: " << bad);
    // Empty, or holding a control character (a tab), it is refused as any profile string is.
    refusedAt(doc, "build_file.name", !bad[0] ? "non-empty" : std::strchr(bad, '\t') ? "without control characters" : "portable");
  }
  json longName = bundledProfileJson();
  longName["materials"][0]["name"] = std::string(65, 'V');
  refusedAt(longName, "materials[0].name", "at most 64");

  json vero = bundledProfileJson();
  vero["materials"][0]["name"] = "Vero";
  vero["materials"][1]["name"] = "VERO";
  refusedAt(vero, "materials[1].name", "case-insensitive");
  json manifestClash = bundledProfileJson();
  manifestClash["build_file"]["name"] = "Manifest.JSON";
  refusedAt(manifestClash, "build_file.name", "job manifest");
  json layerClash = bundledProfileJson();
  layerClash["build_file"]["name"] = "tangoblackplus_0003.png";
  refusedAt(layerClash, "build_file.name", "layer image of TangoBlackPlus");

  CHECK(portableNameProblem("VeroWhitePlus").empty());
  CHECK(portableNameProblem("build.txt").empty());
  CHECK(portableNameProblem("COM10.txt").empty());  // only COM1..COM9 are devices
  CHECK_FALSE(portableNameProblem("nul").empty());
}

TEST_CASE("Every number of a profile is range-checked with its JSON path", "[profile][hostile]") {
  const auto with = [](const std::function<void(json&)>& edit) {
    json doc = bundledProfileJson();
    edit(doc);
    return doc;
  };
  refusedAt(with([](json& d) { d["image"]["padding_voxels"] = {100000, 100000}; }), "image.padding_voxels[0]", "0..65536");
  refusedAt(with([](json& d) { d["image"]["padding_voxels"] = {6000, 16}; }), "image.padding_voxels[0]", "must fit the tray");
  refusedAt(with([](json& d) { d["image"]["padding_voxels"][1] = 18446744073709551615ull; }), "image.padding_voxels[1]", "0..65536");
  refusedAt(with([](json& d) { d["tray_mm"] = {1e5, 390, 200}; }), "tray_mm[0]", "<= 10000");
  refusedAt(with([](json& d) { d["tray_mm"] = {2000, 2000, 200}; }), "tray_mm", "134217728");
  refusedAt(with([](json& d) { d["tray_mm"][2] = 9999; }), "tray_mm[2]", "at most 65536");
  refusedAt(with([](json& d) { d["materials"][0]["density_g_per_ml"] = 1e300; }), "materials[0].density_g_per_ml", "<= 100");
  refusedAt(with([](json& d) { d["materials"][2]["preview_rgb"][1] = 256; }), "materials[2].preview_rgb[1]", "0..255");
  refusedAt(with([](json& d) { d["resolution"]["x_dpi"] = 0; }), "resolution.x_dpi", "1..100000");
  refusedAt(with([](json& d) { d["resolution"]["voxel_size_mm"][2] = 1e-9; }), "resolution.voxel_size_mm[2]", ">= 0.0001");
  refusedAt(with([](json& d) { d["image"]["layer_digits"] = 10; }), "image.layer_digits", "1..9");
  // As wide as a full tray's layer numbers (0 .. 6665 of 0.030 mm): the build file declares the width.
  refusedAt(with([](json& d) { d["image"]["layer_digits"] = 3; }), "image.layer_digits", "expected at least 4: the tray holds up to 6666 layers");
  CHECK_NOTHROW(parseProfile(with([](json& d) { d["tray_mm"][2] = 29.97; d["image"]["layer_digits"] = 3; }).dump(), "999.json"));
  refusedAt(with([](json& d) { d["image"]["column_alignment"] = 1 << 20; }), "image.column_alignment", "8..4096");
  refusedAt(with([](json& d) { d["model_material_slots"] = 17; }), "model_material_slots", "1..16");
  refusedAt(with([](json& d) { d["build_file"]["format_version"] = 0; }), "build_file.format_version", "1..1000");
  refusedAt(with([](json& d) { d["description"] = std::string(5000, 'x'); }), "description", "at most 4096");
  // The bundled profile is inside every limit.
  CHECK_NOTHROW(parseProfile(bundledProfileJson().dump(), "ok.json"));
}

TEST_CASE("Profiles nested too deep or with a key twice are refused while they are parsed", "[profile][hostile]") {
  const std::string text = bundledProfileJson().dump();
  const auto withMember = [&](const std::string& member) { return "{" + member + "," + text.substr(1); };
  // 64 levels in all (the top object and 63 arrays) are allowed; one more is not.
  CHECK_NOTHROW(parseProfile(withMember("\"x\": " + std::string(63, '[') + std::string(63, ']')), "deep.json"));
  const std::vector<ProfileIssue> deep = refusalOf(withMember("\"x\": " + std::string(64, '[') + std::string(64, ']')));
  REQUIRE(deep.size() == 1);
  CHECK(deep[0].path.starts_with("x[0][0]"));
  CHECK_THAT(deep[0].message, Catch::Contains("deeper than 64"));
  // Far deeper than any stack would take, within the size limit: refused just the same.
  const std::vector<ProfileIssue> deeper = refusalOf(std::string(500000, '[') + std::string(500000, ']'));
  REQUIRE(deeper.size() == 1);
  CHECK_THAT(deeper[0].message, Catch::Contains("deeper than 64"));

  const std::vector<ProfileIssue> twice = refusalOf(withMember("\"format\": \"rodfab.printer-profile/1\""));
  REQUIRE(twice.size() == 1);
  CHECK(twice[0].path == "format");
  CHECK_THAT(twice[0].message, Catch::Contains("appears twice"));
  std::string nested = text;
  nested.replace(nested.find("\"x_dpi\":600"), 11, "\"x_dpi\":600,\"x_dpi\":300");
  const std::vector<ProfileIssue> inner = refusalOf(nested);
  REQUIRE(inner.size() == 1);
  CHECK(inner[0].path == "resolution.x_dpi");
  std::string inArray = text;
  inArray.replace(inArray.find("\"name\":\"FullCure705\""), 20, "\"name\":\"FullCure705\",\"name\":\"X\"");
  const std::vector<ProfileIssue> element = refusalOf(inArray);
  REQUIRE(element.size() == 1);
  CHECK(element[0].path == "materials[2].name");
}

TEST_CASE("A profile file is read only when it is a small regular file", "[profile][hostile]") {
  const fs::path dir = scratch("profile-files");
  writeAll(dir / "large.json", Bytes(kMaxProfileBytes + 1, ' '));
  CHECK_THROWS_WITH(readProfile(dir / "large.json"), Catch::Contains("larger than 1048576 bytes"));
  REQUIRE(::mkfifo((dir / "pipe.json").c_str(), 0600) == 0);
  CHECK_THROWS_WITH(readProfile(dir / "pipe.json"), Catch::Contains("pipe.json: is not a regular file"));  // not waited on
  CHECK_THROWS_WITH(readProfile("/dev/zero"), Catch::Contains("/dev/zero: is not a regular file"));
  CHECK_THROWS_WITH(readProfile(dir / "none.json"), Catch::Contains("none.json: cannot open"));
  CHECK_THROWS_WITH(readProfile(dir), Catch::Contains("is not a regular file"));
}

// ---------------------------------------------------------------- replacing, interrupts, staging
