// printer_profiles/: profiles, bitmap codecs, and jobs written from synthetic grids then decoded back
// from their files and compared voxel for voxel; support, checksums, tampering, interrupts, sizes.
#include "printer_profiles/printer_profiles.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <tuple>

using namespace rodfab::printer_profiles;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const Profile& connex3() {
  static const Profile p = loadProfile("stratasys-objet500-connex3");
  return p;
}

const openvdb::Vec3d kOrigin(-3.0, 5.0, 0.25);

openvdb::BoolGrid::Ptr newGrid() {
  openvdb::initialize();
  auto grid = openvdb::BoolGrid::create(false);
  grid->setName("material");
  grid->setTransform(gridTransform(connex3(), kOrigin));
  return grid;
}

fs::path scratchRoot() { return fs::temp_directory_path() / ("rodfab-test-printer-profiles-" + std::to_string(::getpid())); }

// Removes this process's scratch folder when the test program ends.
struct ScratchCleanup {
  ~ScratchCleanup() {
    std::error_code ec;
    fs::remove_all(scratchRoot(), ec);
  }
} scratchCleanup;

// A fresh, empty scratch directory per test.
fs::path scratch(const std::string& name) {
  const fs::path dir = scratchRoot() / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A box with a random Vero/Tango pattern, plus a slab overhanging one side at the top.
openvdb::BoolGrid::Ptr overhangPart(unsigned seed) {
  auto grid = newGrid();
  auto acc = grid->getAccessor();
  std::mt19937 rng(seed);
  std::bernoulli_distribution vero(0.4);
  for (int k = 3; k < 23; ++k)
    for (int j = -7; j < 9; ++j)
      for (int i = 5; i < 21; ++i) acc.setValueOn({i, j, k}, vero(rng));
  for (int k = 23; k < 27; ++k)  // the overhang: wider than the box along x
    for (int j = -7; j < 9; ++j)
      for (int i = 5; i < 47; ++i) acc.setValueOn({i, j, k}, vero(rng));
  return grid;
}

// The band of layers [kBegin, kEnd) of `grid`, as the slicer would hand it over.
openvdb::BoolGrid::Ptr band(const openvdb::BoolGrid& grid, int kBegin, int kEnd) {
  auto out = newGrid();
  auto acc = out->getAccessor();
  for (auto it = grid.cbeginValueOn(); it; ++it)
    if (it.getCoord().z() >= kBegin && it.getCoord().z() < kEnd) acc.setValueOn(it.getCoord(), *it);
  return out;
}

JobSpec specFor(const openvdb::BoolGrid& grid, const fs::path& output) {
  JobSpec spec;
  spec.profile = connex3();
  spec.partBounds = grid.evalActiveVoxelBoundingBox();
  spec.originMm = kOrigin;
  spec.metadata.design = "synthetic";
  spec.metadata.ditherer = "white-noise";
  spec.metadata.seed = 7;
  spec.options.output = output;
  spec.options.contactSheetLayers = 6;
  return spec;
}

JobResult writeJob(const openvdb::BoolGrid& grid, JobSpec spec, int bandLayers) {
  JobWriter writer(std::move(spec));
  const openvdb::CoordBBox box = grid.evalActiveVoxelBoundingBox();
  for (int k = box.min().z(); k <= box.max().z(); k += bandLayers)
    writer.addBand({band(grid, k, std::min(k + bandLayers, box.max().z() + 1)), nullptr, k, std::min(k + bandLayers, box.max().z() + 1)});
  return writer.finalize();
}

Bytes readAll(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void writeAll(const fs::path& file, const Bytes& data) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
}

using Voxel = std::tuple<int, int, int, int>;  // i, j, k, material (1 rigid, 0 rubbery, 2 support)

// Decodes every layer image of a job and maps pixels back to voxels through the manifest's frame.
std::set<Voxel> decodeJob(const fs::path& job, json* manifestOut = nullptr) {
  const auto files = openJobFiles(job);
  const Bytes text = files->read("manifest.json");
  const json manifest = json::parse(text.begin(), text.end());
  if (manifestOut) *manifestOut = manifest;
  const int i0 = manifest["frame"]["first_column_i"], j0 = manifest["frame"]["top_row_j"], k0 = manifest["frame"]["first_layer_k"];
  std::map<std::string, int> code;
  for (const json& m : manifest["materials"])
    code[m["name"]] = m["role"] == "rigid" ? 1 : m["role"] == "rubbery" ? 0 : 2;
  std::set<Voxel> voxels;
  for (const json& layer : manifest["layers"])
    for (const auto& [material, file] : layer["files"].items()) {
      const Bytes data = files->read(file.get<std::string>());
      const std::string name = file.get<std::string>();
      const DecodedBitmap d = name.ends_with(".png") ? decodePng1(data) : decodeBmp(data);
      REQUIRE(d.bitDepth == 1);
      for (int r = 0; r < d.bitmap.height(); ++r)
        for (int c = 0; c < d.bitmap.width(); ++c)
          if (d.bitmap.get(c, r)) voxels.emplace(i0 + c, j0 - r, k0 + layer["layer"].get<int>(), code[material]);
    }
  return voxels;
}

std::set<Voxel> gridVoxels(const openvdb::BoolGrid& grid) {
  std::set<Voxel> voxels;
  for (auto it = grid.cbeginValueOn(); it; ++it) voxels.emplace(it.getCoord().x(), it.getCoord().y(), it.getCoord().z(), *it ? 1 : 0);
  return voxels;
}

}  // namespace

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
  CHECK(bundledProfileNames() == std::vector<std::string>{"stratasys-objet500-connex3"});
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

TEST_CASE("A BMP zip job decodes back to the material grid voxel for voxel and inspects clean", "[job]") {
  const fs::path dir = scratch("roundtrip-bmp");
  const auto grid = overhangPart(11);
  const JobResult result = writeJob(*grid, specFor(*grid, dir / "part.zip"), 5);
  REQUIRE(fs::is_regular_file(dir / "part.zip"));
  json manifest;
  CHECK((decodeJob(dir / "part.zip", &manifest) == gridVoxels(*grid)));

  const InspectReport report = inspectJob(dir / "part.zip");
  INFO(report.defects.size() << " defects, first: " << (report.defects.empty() ? "" : report.defects[0]));
  CHECK(report.ok());
  CHECK(report.layers == 24);
  CHECK(manifest["image"]["width"].get<int>() % 32 == 0);
  CHECK(manifest["profile"]["x_dpi"] == 600);
  CHECK(manifest["layers"].size() == 24);
  CHECK(manifest["layers"][0]["files"]["VeroWhitePlus"] == "VeroWhitePlus_0000.bmp");
  std::uint64_t vero = 0;
  for (auto it = grid->cbeginValueOn(); it; ++it) vero += *it ? 1 : 0;
  CHECK(manifest["statistics"]["materials"]["VeroWhitePlus"]["voxels"] == vero);
  CHECK(result.materials[0].voxels == vero);
  CHECK(result.materials[0].volumeMl == Approx(vero * 0.0423 * 0.0846 * 0.030 / 1000));
  CHECK(manifest["files"].contains("build.txt"));
  CHECK(manifest["files"].contains("previews/projections-material.png"));
  CHECK(manifest["files"].contains("previews/contact-sheet.png"));
  // Only the job is left in the output folder: no temporaries.
  CHECK(std::distance(fs::directory_iterator(dir), fs::directory_iterator()) == 1);

  const auto files = openJobFiles(dir / "part.zip");
  const Bytes build = files->read("build.txt");
  const std::string text(build.begin(), build.end());
  CHECK(text.find("[Build]") == 0);
  CHECK(text.find("Number of slices = 24;") != std::string::npos);
  CHECK(text.find("Layer thickness = 0.03;") != std::string::npos);
  CHECK(text.find("VeroWhitePlus = VeroWhitePlus_xxxx.bmp;") != std::string::npos);
  CHECK(text.find("Support = FullCure705;") != std::string::npos);
  const RgbImage preview = decodePngRgb(files->read("previews/projections-material.png"));
  CHECK(preview.width > 100);
}

TEST_CASE("A PNG directory job decodes back to the grid, with the DPI in pHYs", "[job]") {
  const fs::path dir = scratch("roundtrip-png");
  const auto grid = overhangPart(12);
  JobSpec spec = specFor(*grid, dir / "part");
  spec.options.archive = ArchiveFormat::Directory;
  spec.options.imageFormat = ImageFormat::Png;
  writeJob(*grid, spec, 24);
  REQUIRE(fs::is_directory(dir / "part"));
  CHECK((decodeJob(dir / "part") == gridVoxels(*grid)));
  const DecodedBitmap first = decodePng1(readAll(dir / "part" / "TangoBlackPlus_0000.png"));
  CHECK(first.xPixelsPerMetre == 23622);
  CHECK(first.yPixelsPerMetre == 11811);
  CHECK(first.bitmap.width() % 32 == 0);
  CHECK(inspectJob(dir / "part").ok());
}

TEST_CASE("Job bytes do not depend on the thread count or the band size", "[job]") {
  const fs::path dir = scratch("determinism");
  const auto grid = overhangPart(13);
  // The job's name appears in its previews, so both runs write "job.zip", in different folders.
  fs::create_directories(dir / "one-thread");
  fs::create_directories(dir / "many-threads");
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    writeJob(*grid, specFor(*grid, dir / "one-thread" / "job.zip"), 1);
  }
  writeJob(*grid, specFor(*grid, dir / "many-threads" / "job.zip"), 7);
  const Bytes a = readAll(dir / "one-thread" / "job.zip"), b = readAll(dir / "many-threads" / "job.zip");
  CHECK(a.size() > 1000);
  CHECK((a == b));
}

TEST_CASE("Explicit support fills under the overhang down to the tray and never touches the model", "[job][support]") {
  const fs::path dir = scratch("support");
  const auto grid = overhangPart(14);
  JobSpec spec = specFor(*grid, dir / "supported");
  spec.options.archive = ArchiveFormat::Directory;
  spec.options.support = SupportPolicy::Explicit;
  const JobGeometry geometry = planJob(connex3(), spec.partBounds);
  auto tops = std::make_shared<ColumnTops>(geometry);
  tops->include(*grid);
  spec.supportTops = tops;
  writeJob(*grid, spec, 6);

  std::set<Voxel> support, model;
  for (const Voxel& v : decodeJob(dir / "supported")) (std::get<3>(v) == 2 ? support : model).insert(v);
  CHECK((model == gridVoxels(*grid)));
  // Expected: under the overhang (i in 21..46) every layer from the tray (k = 3) up to below it (k = 22).
  std::set<Voxel> expected;
  for (int k = 3; k < 23; ++k)
    for (int j = -7; j < 9; ++j)
      for (int i = 21; i < 47; ++i) expected.emplace(i, j, k, 2);
  CHECK((support == expected));
  const InspectReport report = inspectJob(dir / "supported");
  CHECK(report.ok());
  REQUIRE(report.materials.size() == 3);
  CHECK(report.materials[2].voxels == expected.size());

  JobSpec noTops = specFor(*grid, dir / "no-tops");
  noTops.options.support = SupportPolicy::Explicit;
  CHECK_THROWS_WITH(JobWriter(noTops), Catch::Contains("ColumnTops"));
}

TEST_CASE("Inspect catches tampering, truncation, flips and a 600/300 swap", "[inspect]") {
  const fs::path dir = scratch("inspect");
  const auto grid = overhangPart(15);

  SECTION("a changed byte in a zip fails its checksum or CRC") {
    writeJob(*grid, specFor(*grid, dir / "job.zip"), 24);
    Bytes zip = readAll(dir / "job.zip");
    // Flip a byte in the middle of the last layer's data (the archive ends with it and the directory).
    zip[zip.size() * 3 / 4] ^= 0x5a;
    writeAll(dir / "tampered.zip", zip);
    CHECK_FALSE(inspectJob(dir / "tampered.zip").ok());
  }
  SECTION("a truncated zip is not a job") {
    writeJob(*grid, specFor(*grid, dir / "job.zip"), 24);
    Bytes zip = readAll(dir / "job.zip");
    zip.resize(zip.size() / 2);
    writeAll(dir / "truncated.zip", zip);
    const InspectReport report = inspectJob(dir / "truncated.zip");
    REQUIRE_FALSE(report.ok());
    CHECK(report.defects[0].find("truncated") != std::string::npos);
  }

  // Directory jobs let a test rewrite one image and its checksum, so only the deeper checks can object.
  JobSpec spec = specFor(*grid, dir / "job");
  spec.options.archive = ArchiveFormat::Directory;
  writeJob(*grid, spec, 24);
  const fs::path layerFile = dir / "job" / "VeroWhitePlus_0021.bmp";
  const auto replaceLayer = [&](const Bytes& data) {
    writeAll(layerFile, data);
    json manifest = json::parse(readAll(dir / "job" / "manifest.json"));
    manifest["files"]["VeroWhitePlus_0021.bmp"] = {{"bytes", data.size()}, {"sha256", sha256Hex(data)}};
    const std::string text = manifest.dump(1);
    writeAll(dir / "job" / "manifest.json", Bytes(text.begin(), text.end()));
  };
  const DecodedBitmap original = decodeBmp(readAll(layerFile));
  const auto hasDefect = [&](const std::string& fragment) {
    const InspectReport report = inspectJob(dir / "job");
    for (const std::string& d : report.defects)
      if (d.find(fragment) != std::string::npos) return true;
    INFO("defects: " << report.defects.size() << (report.defects.empty() ? "" : " first: " + report.defects[0]));
    return false;
  };

  SECTION("an edited file without a new checksum") {
    Bytes data = readAll(layerFile);
    data[100] ^= 1;
    writeAll(layerFile, data);
    CHECK(hasDefect("VeroWhitePlus_0021.bmp: checksum mismatch"));
  }
  SECTION("a layer flipped upside down (mirrored part)") {
    Bitmap flipped(original.bitmap.width(), original.bitmap.height());
    for (int r = 0; r < flipped.height(); ++r)
      for (int c = 0; c < flipped.width(); ++c) flipped.set(c, r, original.bitmap.get(c, flipped.height() - 1 - r));
    replaceLayer(encodeBmp(flipped, 600, 300));
    CHECK(hasDefect("mirrored"));
  }
  SECTION("600 and 300 dpi swapped in the image header") {
    replaceLayer(encodeBmp(original.bitmap, 300, 600));
    CHECK(hasDefect("x and y swapped"));
  }
  SECTION("an 8-bit image") {
    Bytes data = readAll(layerFile);
    data[28] = 8;
    replaceLayer(data);
    CHECK(hasDefect("bits per pixel; expected 1"));
  }
  SECTION("Vero and Tango in one voxel") {
    Bitmap both = original.bitmap;
    const DecodedBitmap tango = decodeBmp(readAll(dir / "job" / "TangoBlackPlus_0021.bmp"));
    for (int r = 0; r < both.height(); ++r)
      for (int c = 0; c < both.width(); ++c)
        if (tango.bitmap.get(c, r)) both.set(c, r);
    replaceLayer(encodeBmp(both, 600, 300));
    CHECK(hasDefect("voxels hold both VeroWhitePlus and TangoBlackPlus"));
  }
  SECTION("a manifest of the wrong shape is reported, not thrown") {
    json manifest = json::parse(readAll(dir / "job" / "manifest.json"));
    manifest["layers"][3] = 5;
    manifest["files"].erase("build.txt");
    const std::string text = manifest.dump(1);
    writeAll(dir / "job" / "manifest.json", Bytes(text.begin(), text.end()));
    CHECK(hasDefect("manifest.json: layers[3]: expected an object, got 5"));
    CHECK(hasDefect("manifest.json: files: lacks build.txt"));
    json broken = json::parse(text);
    broken.erase("frame");
    const std::string brokenText = broken.dump();
    writeAll(dir / "job" / "manifest.json", Bytes(brokenText.begin(), brokenText.end()));
    CHECK(hasDefect("manifest.json"));
  }
  SECTION("a missing layer file") {
    fs::remove(layerFile);
    CHECK(hasDefect("VeroWhitePlus_0021.bmp"));
  }
}

TEST_CASE("An existing job is not overwritten without force", "[job]") {
  const fs::path dir = scratch("force");
  const auto grid = overhangPart(16);
  writeJob(*grid, specFor(*grid, dir / "job.zip"), 24);
  const Bytes before = readAll(dir / "job.zip");
  CHECK_THROWS_WITH(writeJob(*grid, specFor(*grid, dir / "job.zip"), 24), Catch::Contains("--force"));
  CHECK(readAll(dir / "job.zip") == before);
  const auto other = overhangPart(17);
  JobSpec spec = specFor(*other, dir / "job.zip");
  spec.options.force = true;
  writeJob(*other, spec, 24);
  CHECK((decodeJob(dir / "job.zip") == gridVoxels(*other)));
}

TEST_CASE("A failed or interrupted write leaves nothing that looks like a job", "[job][atomic]") {
  const fs::path dir = scratch("interrupt");
  const auto grid = overhangPart(18);
  const auto leftovers = [&] { return std::distance(fs::directory_iterator(dir), fs::directory_iterator()); };

  SECTION("the writer is dropped before finalize") {
    {
      JobWriter writer(specFor(*grid, dir / "job.zip"));
      writer.addBand({band(*grid, 3, 10), nullptr, 3, 10});
    }
    CHECK(leftovers() == 0);
  }
  SECTION("a band with voxels outside its layers is refused and nothing stays") {
    {
      JobWriter writer(specFor(*grid, dir / "job.zip"));
      CHECK_THROWS_WITH(writer.addBand({band(*grid, 3, 12), nullptr, 3, 10}), Catch::Contains("outside the band"));
    }
    CHECK(leftovers() == 0);
  }
  SECTION("finalize before every layer came") {
    {
      JobWriter writer(specFor(*grid, dir / "job.zip"));
      writer.addBand({band(*grid, 3, 10), nullptr, 3, 10});
      CHECK_THROWS_WITH(writer.finalize(), Catch::Contains("never added"));
    }
    CHECK(leftovers() == 0);
  }
  SECTION("the process is killed mid-job") {
    const pid_t child = ::fork();
    REQUIRE(child >= 0);
    if (child == 0) {
      JobWriter writer(specFor(*grid, dir / "job.zip"));
      writer.addBand({band(*grid, 3, 10), nullptr, 3, 10});
      writer.addBand({band(*grid, 10, 20), nullptr, 10, 20});
      ::raise(SIGKILL);
    }
    int status = 0;
    ::waitpid(child, &status, 0);
    REQUIRE(WIFSIGNALED(status));
    CHECK_FALSE(fs::exists(dir / "job.zip"));
    for (const auto& e : fs::directory_iterator(dir)) {
      CHECK(e.path().filename().string().starts_with(".job.zip.rodfab-partial-"));
      CHECK_FALSE(inspectJob(e.path()).ok());
    }
    // The next job for the same target clears the dead writer's leftovers.
    writeJob(*grid, specFor(*grid, dir / "job.zip"), 24);
    CHECK(leftovers() == 1);
  }
}

TEST_CASE("Grids with the wrong voxel size are refused, naming a 600/300 swap", "[job]") {
  const fs::path dir = scratch("swap");
  const auto grid = overhangPart(19);
  JobWriter writer(specFor(*grid, dir / "job.zip"));
  auto swapped = band(*grid, 3, 27);
  swapped->setTransform(openvdb::math::Transform::createLinearTransform(
      openvdb::math::scale<openvdb::Mat4d>(openvdb::Vec3d(0.0846, 0.0423, 0.030))));
  CHECK_THROWS_WITH(writer.addBand({swapped, nullptr, 3, 27}), Catch::Contains("x and y are swapped"));
  CHECK_THROWS_WITH(writer.addBand({band(*grid, 4, 27), nullptr, 4, 27}), Catch::Contains("expected a band from k = 3"));
}

TEST_CASE("Active tiles are written like the voxels they stand for", "[job]") {
  const fs::path dir = scratch("tiles");
  auto grid = newGrid();
  grid->tree().addTile(1, openvdb::Coord(0, 0, 0), true, true);  // an 8x8x8 leaf-sized tile of Vero
  grid->tree().setValueOn(openvdb::Coord(9, 2, 3), false);
  {
    JobWriter writer(specFor(*grid, dir / "tiles.zip"));  // one band: the tile must stay a tile
    writer.addBand({grid, nullptr, 0, 8});
    writer.finalize();
  }
  std::set<Voxel> expected;
  for (int k = 0; k < 8; ++k)
    for (int j = 0; j < 8; ++j)
      for (int i = 0; i < 8; ++i) expected.emplace(i, j, k, 1);
  expected.emplace(9, 2, 3, 0);
  CHECK((decodeJob(dir / "tiles.zip") == expected));
}
