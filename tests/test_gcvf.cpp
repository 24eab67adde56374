// The J750/J850 family through GrabCAD Voxel Print: the profile and its print modes, the .gcvf writer
// (layers decoded with libpng's simplified API and ConfigFile.xml with libxml2's XPath, not with the
// writer's or inspect's code), inspect's ConfigFile.xml checks on hostile XML, and calibration materials.
#include "calibration/calibration_file.hpp"
#include "printer_profiles/gcvf_writer.hpp"
#include "printer_profiles/inspect.hpp"
#include "printer_profiles/inspect_gcvf.hpp"
#include "printer_profiles/job_writer.hpp"
#include "printer_profiles/profile.hpp"
#include "voxel/printer_grid.hpp"
#include "slicer/calibration_materials.hpp"
#include "tests/temp_dir.hpp"

#include <catch2/catch.hpp>
#include <libxml/parser.h>
#include <libxml/xpath.h>
#include <nlohmann/json.hpp>
#include <png.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <random>

using namespace rodfab::printer_profiles;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const Profile& j750() {
  static const Profile p = loadProfile("stratasys-j750-j850");
  return p;
}

std::string readText(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

json bundledJson() { return json::parse(readText(bundledProfileDir() / "stratasys-j750-j850.json")); }

// The JSON path of every issue the edited profile is refused for.
std::vector<std::string> refusedPaths(const std::function<void(json&)>& edit) {
  json doc = bundledJson();
  edit(doc);
  try {
    parseProfile(doc.dump(), "edited.json");
  } catch (const ProfileError& e) {
    std::vector<std::string> paths;
    for (const ProfileIssue& i : e.issues()) paths.push_back(i.path);
    return paths;
  }
  return {};
}

fs::path scratch(const std::string& name) {
  const fs::path dir = rodfab::test::processScratch("gcvf", name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

const openvdb::Vec3d kOrigin(1.0, -2.0, 0.5);

// A random rigid/rubbery block with a notch, at the profile's voxel.
openvdb::BoolGrid::Ptr part(const Profile& profile, unsigned seed) {
  openvdb::initialize();
  auto grid = openvdb::BoolGrid::create(false);
  grid->setTransform(rodfab::voxel::printerTransform(profile.voxelSize(), kOrigin));
  auto acc = grid->getAccessor();
  std::mt19937 rng(seed);
  std::bernoulli_distribution rigid(0.6);
  for (int k = 2; k < 19; ++k)
    for (int j = -5; j < 11; ++j)
      for (int i = 3; i < 40; ++i)
        if (!(i > 20 && j > 4 && k > 10)) acc.setValueOn({i, j, k}, rigid(rng));
  return grid;
}

openvdb::BoolGrid::Ptr band(const openvdb::BoolGrid& grid, int k0, int k1) {
  auto out = openvdb::BoolGrid::create(false);
  out->setTransform(grid.transform().copy());
  auto acc = out->getAccessor();
  for (auto it = grid.cbeginValueOn(); it; ++it)
    if (it.getCoord().z() >= k0 && it.getCoord().z() < k1) acc.setValueOn(it.getCoord(), *it);
  return out;
}

JobResult writeGcvf(const Profile& profile, const openvdb::BoolGrid& grid, const fs::path& out, int bandLayers,
                    ArchiveFormat archive = ArchiveFormat::Zip) {
  JobSpec spec;
  spec.profile = profile;
  spec.partBounds = grid.evalActiveVoxelBoundingBox();
  spec.originMm = kOrigin;
  spec.metadata.ditherer = "white-noise";
  spec.options.output = out;
  spec.options.archive = archive;
  spec.options.contactSheetLayers = 4;
  JobWriter writer(std::move(spec));
  const openvdb::CoordBBox box = grid.evalActiveVoxelBoundingBox();
  for (int k = box.min().z(); k <= box.max().z(); k += bandLayers) {
    const int end = std::min(k + bandLayers, box.max().z() + 1);
    writer.addBand({band(grid, k, end), nullptr, k, end});
  }
  return writer.finalize();
}

// libpng's simplified API, as any PNG reader would do it: RGBA bytes, row-major.
std::vector<std::uint8_t> decodeRgba(const Bytes& data, int& width, int& height) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  REQUIRE(png_image_begin_read_from_memory(&image, data.data(), data.size()));
  image.format = PNG_FORMAT_RGBA;
  std::vector<std::uint8_t> pixels(PNG_IMAGE_SIZE(image));
  REQUIRE(png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr));
  width = static_cast<int>(image.width);
  height = static_cast<int>(image.height);
  return pixels;
}

std::string xpathText(xmlDoc* doc, const char* path) {
  xmlXPathContext* ctx = xmlXPathNewContext(doc);
  xmlXPathObject* result = xmlXPathEvalExpression(reinterpret_cast<const xmlChar*>(path), ctx);
  std::string text;
  if (result && result->type == XPATH_STRING) text = reinterpret_cast<const char*>(result->stringval);
  xmlXPathFreeObject(result);
  xmlXPathFreeContext(ctx);
  return text;
}

}  // namespace

TEST_CASE("The J750/J850 profile: 600 x 300 dpi, 27 um (high-speed) or 14 um (high-mix), RGBA materials", "[gcvf][profile]") {
  const Profile& p = j750();
  CHECK(p.jobFormat == JobFormat::Gcvf);
  CHECK(p.xDpi == 600);
  CHECK(p.yDpi == 300);
  CHECK(p.voxelSizeMm[2] == Approx(0.027));
  CHECK(p.printMode == "high-speed");
  REQUIRE(p.printModes.size() == 2);
  CHECK(p.material(MaterialRole::Rigid).name == "VeroUltraWhite");
  CHECK(p.material(MaterialRole::Rubbery).name == "Agilus30Black");
  CHECK(p.imageBitDepth() == 32);
  CHECK(p.buildFileName == "ConfigFile.xml");
  CHECK(p.layerFileName(p.material(MaterialRole::Rigid), 12, ImageFormat::Png) == "layer_12.png");
  CHECK(p.layerFileName(p.material(MaterialRole::Rubbery), 0, ImageFormat::Png) == "layer_0.png");

  const Profile mix = withPrintMode(p, "high-mix");
  CHECK(mix.voxelSizeMm[2] == Approx(0.014));
  CHECK(mix.voxelSizeMm[0] == p.voxelSizeMm[0]);
  CHECK(mix.printMode == "high-mix");
  CHECK_THROWS_WITH(withPrintMode(p, "turbo"), Catch::Contains("no print mode \"turbo\" (modes: high-speed, high-mix)"));
  CHECK_THROWS_WITH(withPrintMode(loadProfile("stratasys-objet500-connex3"), "high-mix"), Catch::Contains("has no print modes"));
}

TEST_CASE("gcvf profiles are validated: colours, names, format, print modes", "[gcvf][profile]") {
  CHECK(refusedPaths([](json&) {}).empty());
  using Paths = std::vector<std::string>;
  CHECK(refusedPaths([](json& d) { d["materials"][1]["rgba"] = d["materials"][0]["rgba"]; }) == Paths{"materials[1].rgba"});
  CHECK(refusedPaths([](json& d) { d["materials"][0]["rgba"] = d["gcvf"]["background_rgba"]; }) == Paths{"materials[0].rgba"});
  CHECK(refusedPaths([](json& d) { d["materials"][0].erase("rgba"); }) == Paths{"materials[0].rgba"});
  CHECK(refusedPaths([](json& d) { d["materials"][0]["rgba"] = {1, 2, 3}; }) == Paths{"materials[0].rgba"});
  CHECK(refusedPaths([](json& d) { d["materials"][0]["rgba"] = {1, 2, 3, 256}; }) == Paths{"materials[0].rgba[3]"});
  CHECK(refusedPaths([](json& d) { d["image"]["format"] = "bmp"; }) == Paths{"image.format"});
  CHECK(refusedPaths([](json& d) { d["image"]["bit_depth"] = 1; }) == Paths{"image.bit_depth"});
  CHECK(refusedPaths([](json& d) { d["image"]["layer_digits"] = 4; }) == Paths{"image.layer_digits"});
  CHECK(refusedPaths([](json& d) { d["build_file"]["name"] = "build.txt"; }) == Paths{"build_file.name"});
  CHECK(refusedPaths([](json& d) { d["support"]["policy"] = "explicit"; }) == Paths{"support.policy"});
  CHECK(refusedPaths([](json& d) { d.erase("gcvf"); }) == Paths{"gcvf"});
  CHECK(refusedPaths([](json& d) { d["gcvf"]["max_number_of_colors"] = 2; }) == Paths{"gcvf.max_number_of_colors"});
  CHECK(refusedPaths([](json& d) { d["gcvf"]["image_file_prefix"] = "../layer_"; }) == Paths{"gcvf.image_file_prefix"});
  CHECK(refusedPaths([](json& d) { d["output"]["format"] = "3mf"; }).at(0) == "output.format");
  CHECK(refusedPaths([](json& d) { d["resolution"]["print_modes"][0]["layer_thickness_mm"] = 0.014; }) ==
        Paths{"resolution.print_modes[0].layer_thickness_mm"});
  CHECK(refusedPaths([](json& d) { d["resolution"]["print_modes"][1]["name"] = "high-speed"; }) ==
        Paths{"resolution.print_modes[1].name"});
  CHECK(refusedPaths([](json& d) { d["resolution"]["print_modes"][1]["layer_thickness_mm"] = 0.001; }) ==
        Paths{"resolution.print_modes[1].layer_thickness_mm"});  // 200,000 layers: more than any tray may hold
  CHECK(refusedPaths([](json& d) { d["resolution"]["print_modes"] = json::array(); }) == Paths{"resolution.print_modes"});
}

TEST_CASE("A .gcvf holds the part: every pixel is the voxel's material colour, counts as ConfigFile.xml says", "[gcvf][writer]") {
  for (const std::string mode : {"high-speed", "high-mix"}) {
    const Profile profile = withPrintMode(j750(), mode);
    const auto grid = part(profile, 11);
    const fs::path dir = scratch("decode-" + mode);
    const JobResult job = writeGcvf(profile, *grid, dir / "part.gcvf", 5);
    const auto files = openJobFiles(job.path);
    const Bytes manifestText = files->read("manifest.json");
    const json manifest = json::parse(manifestText.begin(), manifestText.end());
    const int i0 = manifest["frame"]["first_column_i"], j0 = manifest["frame"]["top_row_j"], k0 = manifest["frame"]["first_layer_k"];
    const auto& rigid = profile.material(MaterialRole::Rigid).rgba;
    const auto& rubbery = profile.material(MaterialRole::Rubbery).rgba;
    const auto& background = profile.gcvf.backgroundRgba;

    std::map<std::string, std::uint64_t> counted;
    auto acc = grid->getConstAccessor();
    for (int l = 0; l < job.geometry.layers; ++l) {
      int w = 0, h = 0;
      const std::vector<std::uint8_t> px = decodeRgba(files->read("layer_" + std::to_string(l) + ".png"), w, h);
      REQUIRE(w == job.geometry.width);
      REQUIRE(h == job.geometry.height);
      for (int r = 0; r < h; ++r)
        for (int c = 0; c < w; ++c) {
          const std::uint8_t* p = &px[(static_cast<std::size_t>(r) * w + c) * 4];
          const std::array<unsigned char, 4> got{p[0], p[1], p[2], p[3]};
          bool value = false;
          const bool on = acc.probeValue({i0 + c, j0 - r, k0 + l}, value);
          const auto& want = !on ? background : value ? rigid : rubbery;
          if (got != want) FAIL("layer " << l << " column " << c << " row " << r << ": wrong colour");
          if (on) ++counted[value ? "VeroUltraWhite" : "Agilus30Black"];
        }
    }
    CHECK(counted["VeroUltraWhite"] + counted["Agilus30Black"] == grid->activeVoxelCount());

    const Bytes xml = files->read("ConfigFile.xml");
    xmlDoc* doc = xmlReadMemory(reinterpret_cast<const char*>(xml.data()), static_cast<int>(xml.size()), "ConfigFile.xml", nullptr,
                                XML_PARSE_NONET);
    REQUIRE(doc);
    CHECK(xpathText(doc, "string(/GCVF/Resolution/SliceThicknessNanoMeter)") == (mode == "high-mix" ? "14000" : "27000"));
    CHECK(xpathText(doc, "string(/GCVF/SliceRange/NumberOfSlices)") == std::to_string(job.geometry.layers));
    CHECK(xpathText(doc, "string(/GCVF/SliceDimensions/SliceWidth)") == std::to_string(job.geometry.width));
    CHECK(xpathText(doc, "string(/GCVF/MaterialList/Material[Name='VeroUltraWhite']/VoxelCount)") ==
          std::to_string(counted["VeroUltraWhite"]));
    CHECK(xpathText(doc, "string(/GCVF/MaterialList/Material[Name='Agilus30Black']/VoxelCount)") ==
          std::to_string(counted["Agilus30Black"]));
    CHECK(xpathText(doc, "string(/GCVF/MaterialList/Material[Name='Agilus30Black']/RGBA)") == "0 0 255 255");
    xmlFreeDoc(doc);
    CHECK(manifest["profile"]["print_mode"] == mode);
    CHECK(inspectJob(job.path).ok());
  }
}

TEST_CASE("A .gcvf has the same bytes for any band size, the folder form the same layers", "[gcvf][writer]") {
  const auto grid = part(j750(), 5);
  std::string first;
  for (const int bandLayers : {1, 4, 64}) {
    const fs::path dir = scratch("bands-" + std::to_string(bandLayers));
    const JobResult job = writeGcvf(j750(), *grid, dir / "part.gcvf", bandLayers);
    const std::string bytes = readText(job.path);
    if (first.empty()) first = bytes;
    CHECK(bytes == first);
  }
  const fs::path dir = scratch("folder");
  const JobResult folder = writeGcvf(j750(), *grid, dir / "part", 7, ArchiveFormat::Directory);
  const fs::path zipDir = scratch("zip");
  const JobResult zip = writeGcvf(j750(), *grid, zipDir / "part", 7);
  const auto a = openJobFiles(folder.path), b = openJobFiles(zip.path);
  CHECK(a->read("ConfigFile.xml") == b->read("ConfigFile.xml"));
  for (int l = 0; l < folder.geometry.layers; ++l)
    CHECK(a->read("layer_" + std::to_string(l) + ".png") == b->read("layer_" + std::to_string(l) + ".png"));
  CHECK(!fs::exists(folder.path / "build.txt"));
}

TEST_CASE("A gcvf job refuses explicit support and BMP layers", "[gcvf][writer]") {
  const auto grid = part(j750(), 1);
  JobSpec spec;
  spec.profile = j750();
  spec.partBounds = grid->evalActiveVoxelBoundingBox();
  spec.originMm = kOrigin;
  spec.options.output = scratch("refuse") / "x.gcvf";
  spec.options.imageFormat = ImageFormat::Bmp;
  CHECK_THROWS_WITH(JobWriter(spec), Catch::Contains("GrabCAD"));
  spec.options.imageFormat.reset();
  spec.options.support = SupportPolicy::Explicit;
  CHECK_THROWS_WITH(JobWriter(spec), Catch::Contains("GrabCAD"));
}

TEST_CASE("ConfigFile.xml: what inspect finds in hostile or inconsistent files", "[gcvf][inspect]") {
  const Profile& p = j750();
  const std::vector<MaterialTotals> counted = {{"VeroUltraWhite", MaterialRole::Rigid, 10, 0, 0},
                                               {"Agilus30Black", MaterialRole::Rubbery, 3, 0, 0}};
  const std::string good = gcvfConfigXml(p, 64, 32, 7, {{&p.material(MaterialRole::Rigid), 10}, {&p.material(MaterialRole::Rubbery), 3}});
  const auto problems = [&](const std::string& xml) {
    return checkGcvfConfig(std::span(reinterpret_cast<const std::uint8_t*>(xml.data()), xml.size()), p, 64, 32, 7, counted);
  };
  const auto edited = [&](const std::string& from, const std::string& to) {
    std::string x = good;
    const std::size_t at = x.find(from);
    REQUIRE(at != std::string::npos);
    return x.replace(at, from.size(), to);
  };
  CHECK(problems(good).empty());
  CHECK_THAT(problems(edited("<VoxelCount>3<", "<VoxelCount>4<")).at(0), Catch::Contains("Material[2]/VoxelCount: expected \"3\", found \"4\""));
  CHECK_THAT(problems(edited("<Version>2</Version>", "")).at(0), Catch::Contains("GCVF/Version: missing"));
  CHECK_THAT(problems(edited("<Version>2</Version>", "<Version>2</Version><Version>2</Version>")).at(0),
             Catch::Contains("GCVF/Version: appears 2 times"));
  CHECK_THAT(problems(edited("<GCVF>", "<GCVX>")).at(0), Catch::Contains("not well-formed"));
  CHECK_THAT(problems(edited("<SliceWidth>64<", "<SliceWidth>65<")).at(0), Catch::Contains("SliceWidth: expected \"64\""));
  CHECK_THAT(problems(edited("<Name>Agilus30Black<", "<Name>TangoBlackPlus<")).at(0), Catch::Contains("Material[2]/Name"));
  CHECK_THAT(problems(edited("</MaterialList>", "<Material><Name>X</Name></Material></MaterialList>")).at(0),
             Catch::Contains("lists 3 materials"));
  // Counts unknown (a layer could not be read): VoxelCount need only be a whole number.
  const auto uncounted = [&](const std::string& xml) {
    return checkGcvfConfig(std::span(reinterpret_cast<const std::uint8_t*>(xml.data()), xml.size()), p, 64, 32, 7, counted, false);
  };
  CHECK(uncounted(edited("<VoxelCount>3<", "<VoxelCount>4<")).empty());
  CHECK_THAT(uncounted(edited("<VoxelCount>3<", "<VoxelCount>-4<")).at(0), Catch::Contains("VoxelCount: expected a whole number"));
  CHECK_THAT(problems("").at(0), Catch::Contains("not well-formed"));
  CHECK_THAT(problems("<a>").at(0), Catch::Contains("not well-formed"));

  // Entities are never expanded and nothing outside the file is read: a billion-laughs document and an
  // external entity are merely wrong.
  std::string bomb = "<?xml version=\"1.0\"?><!DOCTYPE GCVF [<!ENTITY l0 \"lol\">";
  for (int n = 1; n < 10; ++n) {
    bomb += "<!ENTITY l" + std::to_string(n) + " \"";
    for (int r = 0; r < 10; ++r) bomb += "&l" + std::to_string(n - 1) + ";";
    bomb += "\">";
  }
  bomb += "]><GCVF><Version>&l9;</Version></GCVF>";
  const auto bombProblems = problems(bomb);
  REQUIRE(!bombProblems.empty());
  for (const std::string& s : bombProblems) CHECK(s.size() < 400);
  const std::string external = "<?xml version=\"1.0\"?><!DOCTYPE GCVF [<!ENTITY x SYSTEM \"file:///etc/hostname\">]>"
                               "<GCVF><Version>&x;</Version></GCVF>";
  const auto externalProblems = problems(external);
  REQUIRE(!externalProblems.empty());
  CHECK_THAT(externalProblems.at(0), Catch::Contains("GCVF/Version"));
}

TEST_CASE("The XML writer escapes text", "[gcvf][writer]") {
  Profile p = j750();
  p.printer = "J750 <lab & \"co\">";
  const std::string xml = gcvfConfigXml(p, 8, 8, 1, {});
  CHECK_THAT(xml, Catch::Contains("J750 &lt;lab &amp; &quot;co&quot;&gt;"));
  // The name also goes into a comment, where XML allows no "--" and no '-' at the end: inspect's parser
  // (libxml2) reads the file (it refused a printer named so, so that every job failed its own check).
  for (const std::string name : {"J750 -- lab", "J750 ---", "J750-", "-"}) {
    p.printer = name;
    const std::string named = gcvfConfigXml(p, 64, 32, 7, {{&p.material(MaterialRole::Rigid), 10}, {&p.material(MaterialRole::Rubbery), 3}});
    const std::vector<MaterialTotals> counted = {{"VeroUltraWhite", MaterialRole::Rigid, 10, 0, 0},
                                                 {"Agilus30Black", MaterialRole::Rubbery, 3, 0, 0}};
    INFO(name);
    CHECK(checkGcvfConfig(std::span(reinterpret_cast<const std::uint8_t*>(named.data()), named.size()), p, 64, 32, 7, counted).empty());
  }
}

TEST_CASE("Calibrations record their materials, another pair is refused unless forced or the bundled stand-in", "[gcvf][calibration]") {
  using rodfab::slicer::checkCalibrationMaterials;
  const rodfab::calibration::Calibration bundled = rodfab::calibration::loadDefaultCalibration();
  CHECK(bundled.record().rigidMaterial == "VeroWhitePlus");
  CHECK(bundled.record().rubberyMaterial == "TangoBlackPlus");
  // Written and read back.
  const json written = json::parse(rodfab::calibration::calibrationToJson(bundled).dump());
  CHECK(written["materials"] == json{{"rigid", "VeroWhitePlus"}, {"rubbery", "TangoBlackPlus"}});
  CHECK(rodfab::calibration::calibrationFromJson(written, "x.json").record().rubberyMaterial == "TangoBlackPlus");
  json bad = written;
  bad["materials"] = {{"rigid", "VeroUltraWhite"}};
  CHECK_THROWS_WITH(rodfab::calibration::calibrationFromJson(bad, "x.json"), Catch::Contains("x.json: materials.rubbery: missing"));
  bad["materials"] = {{"rigid", "A"}, {"rubbery", "B"}, {"support", "C"}};
  CHECK_THROWS_WITH(rodfab::calibration::calibrationFromJson(bad, "x.json"), Catch::Contains("materials.support: unknown key"));

  const Profile connex3 = loadProfile("stratasys-objet500-connex3");
  CHECK(checkCalibrationMaterials(bundled, "cal.json", connex3, true, false).message.empty());
  CHECK(checkCalibrationMaterials(bundled, "cal.json", connex3, false, false).message.empty());
  const auto standIn = checkCalibrationMaterials(bundled, "cal.json", j750(), true, false);
  CHECK(!standIn.refused);
  CHECK_THAT(standIn.message, Catch::StartsWith("stand-in calibration") && Catch::Contains("coupons --profile stratasys-j750-j850"));
  const auto refused = checkCalibrationMaterials(bundled, "cal.json", j750(), false, false);
  CHECK(refused.refused);
  CHECK_THAT(refused.message, Catch::Contains("--allow-calibration-materials-mismatch"));
  const auto forced = checkCalibrationMaterials(bundled, "cal.json", j750(), false, true);
  CHECK(!forced.refused);
  CHECK_THAT(forced.message, Catch::Contains("used anyway"));
  json unrecorded = written;
  unrecorded.erase("materials");
  const auto old = rodfab::calibration::calibrationFromJson(unrecorded, "old.json");
  const auto oldCheck = checkCalibrationMaterials(old, "old.json", j750(), false, false);
  CHECK(!oldCheck.refused);
  CHECK_THAT(oldCheck.message, Catch::Contains("records no materials"));
}
