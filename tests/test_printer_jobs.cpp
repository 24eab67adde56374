// printer_profiles/ jobs: written from synthetic grids, then decoded back from their files and compared
// voxel for voxel; support, checksums, tampering, force, atomic replacement, interrupts, staging
// folders and previews. Profiles, bitmaps and the layout: tests/test_printer_profiles.cpp.
#include "printer_profiles/previews.hpp"  // internal: the views' memory
#include "common/xxh128.hpp"
#include "printer_profiles/printer_profiles.hpp"
#include "tests/printer_profiles_fixture.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <csignal>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <tuple>

using namespace rodfab::printer_profiles;
namespace fs = std::filesystem;
using nlohmann::json;
using rodfab::test::connex3;
using rodfab::test::readAll;
using rodfab::test::scratch;
using rodfab::test::writeAll;

namespace {

const openvdb::Vec3d kOrigin(-3.0, 5.0, 0.25);

openvdb::BoolGrid::Ptr newGrid() {
  openvdb::initialize();
  auto grid = openvdb::BoolGrid::create(false);
  grid->setName("material");
  grid->setTransform(rodfab::test::profileTransform(connex3(), kOrigin));
  return grid;
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

TEST_CASE("Inspect catches tampering and truncation of a zip job", "[inspect]") {
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
}

TEST_CASE("Inspect catches edits, flips, a 600/300 swap and mixed voxels in a folder job", "[inspect]") {
  const fs::path dir = scratch("inspect-folder");
  const auto grid = overhangPart(15);
  // Directory jobs let a test rewrite one image and its checksum, so only the deeper checks can object.
  JobSpec spec = specFor(*grid, dir / "job");
  spec.options.archive = ArchiveFormat::Directory;
  writeJob(*grid, spec, 24);
  const fs::path layerFile = dir / "job" / "VeroWhitePlus_0021.bmp";
  const auto replaceLayer = [&](const Bytes& data) {
    writeAll(layerFile, data);
    json manifest = json::parse(readAll(dir / "job" / "manifest.json"));
    manifest["files"]["VeroWhitePlus_0021.bmp"] = {{"bytes", data.size()}, {"xxh128", rodfab::common::xxh128Hex(data)}};
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

namespace {

// Everything below `root` without following links: relative path -> kind and contents (bytes or link
// target), so a folder can be compared byte for byte before and after.
std::map<std::string, std::string> snapshot(const fs::path& root) {
  std::map<std::string, std::string> out;
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator(); ++it) {
    const std::string name = fs::relative(it->path(), root).generic_string();
    const fs::file_status status = it->symlink_status();
    if (fs::is_symlink(status)) out[name] = "link:" + fs::read_symlink(it->path()).string();
    else if (fs::is_directory(status)) out[name] = "dir";
    else if (!fs::is_regular_file(status)) out[name] = "special";
    else {
      const Bytes data = readAll(it->path());
      out[name] = "file:" + std::string(data.begin(), data.end());
    }
  }
  return out;
}

// A zip whose entries are (name, text) in this order.
void writeTestZip(const fs::path& file, const std::vector<std::pair<std::string, std::string>>& entries) {
  std::vector<ZipMemoryEntry> zip;
  for (const auto& [name, text] : entries)
    zip.push_back({name, std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size())});
  writeZipFromMemory(file, zip);
}

}  // namespace

TEST_CASE("Force replaces only rodfab jobs: anything else is refused and left byte for byte", "[job][force]") {
  const fs::path dir = scratch("force-refusals");
  const auto grid = overhangPart(21);
  writeJob(*grid, specFor(*grid, dir / "real.zip"), 24);
  JobSpec realDir = specFor(*grid, dir / "real-dir");
  realDir.options.archive = ArchiveFormat::Directory;
  writeJob(*grid, realDir, 24);
  // A user's folder, an empty one, a file, foreign zips, a link to a job, a job folder with a file added.
  fs::create_directories(dir / "mydata" / "sub");
  writeAll(dir / "mydata" / "notes.txt", Bytes{'h', 'i'});
  writeAll(dir / "mydata" / "sub" / "manifest.json", Bytes{'{', '}'});
  fs::create_directories(dir / "empty");
  writeAll(dir / "thesis.zip", Bytes{'n', 'o', 't', ' ', 'a', ' ', 'z', 'i', 'p'});
  writeTestZip(dir / "photos.zip", {{"IMG_0001.jpg", "jpeg"}, {"manifest.json", std::string("{\"format\": \"") + kJobFormat + "\"}"}});
  writeTestZip(dir / "other-tool.zip", {{"manifest.json", "{\"format\": \"other.job/1\", \"files\": {}}"}});
  writeTestZip(dir / "deep.zip", {{"manifest.json", std::string(100000, '[') + std::string(100000, ']')}});
  fs::create_symlink(dir / "real.zip", dir / "link.zip");
  fs::create_symlink(dir / "mydata", dir / "link-dir");
  fs::copy(dir / "real-dir", dir / "job-plus", fs::copy_options::recursive);
  writeAll(dir / "job-plus" / "my-notes.txt", Bytes{'!'});
  fs::copy(dir / "real-dir", dir / "job-plus-preview", fs::copy_options::recursive);
  writeAll(dir / "job-plus-preview" / "previews" / "mine.png", Bytes{'!'});
  REQUIRE(::mkfifo((dir / "pipe").c_str(), 0600) == 0);
  const auto before = snapshot(dir);

  const std::vector<std::pair<std::string, std::string>> cases = {
      {"mydata", "a folder without a rodfab job manifest"},
      {"mydata/", "a folder without a rodfab job manifest"},
      {"empty", "a folder without a rodfab job manifest"},
      {"thesis.zip", "a file that is not a zip archive"},
      {"photos.zip", "whose first entry is not a rodfab job manifest"},
      {"other-tool.zip", "is not a rodfab job manifest"},
      {"deep.zip", "is not a rodfab job manifest"},
      {"link.zip", "a symbolic link"},
      {"link-dir", "a symbolic link"},
      {"job-plus", "'my-notes.txt', which is not part of that job"},
      {"job-plus-preview", "'previews/mine.png', which is not part of that job"},
      {"pipe", "a named pipe"},
  };
  for (const auto& [name, what] : cases)
    for (const bool force : {true, false}) {
      INFO(name << (force ? " with force" : " without force"));
      JobSpec spec = specFor(*grid, dir.string() + "/" + name);
      spec.options.force = force;
      CHECK_THROWS_WITH(writeJob(*grid, spec, 24), Catch::Contains(what) && Catch::Contains("rodfab replaces only its own jobs"));
    }
  CHECK((snapshot(dir) == before));  // every refused path intact, and no temporaries anywhere
  // Names reserved for staging folders (a later job would remove such a job as a dead writer's).
  CHECK_THROWS_WITH(JobWriter(specFor(*grid, dir / ".job.zip.rodfab-partial-1-0")), Catch::Contains("named like rodfab's hidden staging"));
  CHECK_THROWS_WITH(JobWriter(specFor(*grid, dir / ".")), Catch::Contains("give the job a name of its own"));
  CHECK((snapshot(dir) == before));
}

TEST_CASE("Force replaces a rodfab job, zip or folder, by one of either kind", "[job][force]") {
  const fs::path dir = scratch("force-replace");
  const auto first = overhangPart(22), second = overhangPart(23);
  for (const ArchiveFormat oldFormat : {ArchiveFormat::Zip, ArchiveFormat::Directory})
    for (const ArchiveFormat newFormat : {ArchiveFormat::Zip, ArchiveFormat::Directory}) {
      INFO(toString(oldFormat) << " replaced by " << toString(newFormat));
      fs::remove_all(dir / "job");
      JobSpec old = specFor(*first, dir / "job");
      old.options.archive = oldFormat;
      writeJob(*first, old, 24);
      JobSpec spec = specFor(*second, dir / "job");
      spec.options.archive = newFormat;
      CHECK_THROWS_WITH(writeJob(*second, spec, 24), Catch::Contains("already exists there; use --force"));
      spec.options.force = true;
      writeJob(*second, spec, 24);
      CHECK(fs::is_directory(dir / "job") == (newFormat == ArchiveFormat::Directory));
      CHECK((decodeJob(dir / "job") == gridVoxels(*second)));
      CHECK(inspectJob(dir / "job").ok());
      CHECK(std::distance(fs::directory_iterator(dir), fs::directory_iterator()) == 1);  // no old job, no temporaries
    }
}

TEST_CASE("An interrupt at any check of finalize leaves the target as it was", "[job][atomic][interrupt]") {
  const fs::path dir = scratch("interrupt-checks");
  const auto first = overhangPart(24), second = overhangPart(25);
  struct Stop {};
  for (const ArchiveFormat format : {ArchiveFormat::Zip, ArchiveFormat::Directory})
    for (const bool replacing : {false, true}) {
      fs::remove_all(dir);
      fs::create_directories(dir);
      if (replacing) writeJob(*first, specFor(*first, dir / "job.zip"), 24);
      const auto before = snapshot(dir);
      // Checks: as finalize begins, after the zip is built (zip jobs), before the rename, after it.
      const int checks = format == ArchiveFormat::Zip ? 4 : 3;
      for (int stopAt = 1; stopAt <= checks; ++stopAt) {
        INFO(toString(format) << (replacing ? ", replacing a job" : ", new target") << ", interrupted at check " << stopAt);
        int calls = 0;
        JobSpec spec = specFor(*second, dir / "job.zip");
        spec.options.archive = format;
        spec.options.force = replacing;
        spec.options.checkInterrupt = [&] {
          if (++calls == stopAt) throw Stop{};
        };
        CHECK_THROWS_AS(writeJob(*second, spec, 24), Stop);
        CHECK(calls == stopAt);
        CHECK((snapshot(dir) == before));  // the old job back, or nothing; no temporaries
      }
      int calls = 0;
      JobSpec spec = specFor(*second, dir / "job.zip");
      spec.options.archive = format;
      spec.options.force = replacing;
      spec.options.checkInterrupt = [&] { ++calls; };
      const JobResult result = writeJob(*second, spec, 24);
      CHECK(calls == checks);
      CHECK((decodeJob(dir / "job.zip") == gridVoxels(*second)));
      // Taken back after finalize returned (a late signal): only our own job is removed.
      CHECK(withdrawJob(result));
      CHECK(fs::is_empty(dir));
      CHECK_FALSE(withdrawJob(result));
    }
}

TEST_CASE("withdrawJob removes nothing that is not the job it wrote", "[job][interrupt]") {
  const fs::path dir = scratch("withdraw");
  const auto grid = overhangPart(26);
  const JobResult result = writeJob(*grid, specFor(*grid, dir / "job.zip"), 24);
  fs::rename(dir / "job.zip", dir / "moved.zip");
  writeAll(dir / "job.zip", Bytes{'u', 's', 'e', 'r'});  // someone else's file now has the name
  CHECK_FALSE(withdrawJob(result));
  CHECK((readAll(dir / "job.zip") == Bytes{'u', 's', 'e', 'r'}));
  CHECK(fs::exists(dir / "moved.zip"));
}

TEST_CASE("Staging folders of dead writers go, whatever their target; live ones and strangers stay", "[job][atomic]") {
  const fs::path dir = scratch("stale-staging");
  const auto grid = overhangPart(27);
  // A writer killed mid-job (SIGKILL: no cleanup at all).
  const pid_t killed = ::fork();
  REQUIRE(killed >= 0);
  if (killed == 0) {
    JobWriter writer(specFor(*grid, dir / "killed.zip"));
    writer.addBand({band(*grid, 3, 10), nullptr, 3, 10});
    writer.addBand({band(*grid, 10, 20), nullptr, 10, 20});
    ::raise(SIGKILL);
  }
  int status = 0;
  ::waitpid(killed, &status, 0);
  REQUIRE(WIFSIGNALED(status));
  std::vector<fs::path> dead;
  for (const auto& e : fs::directory_iterator(dir)) dead.push_back(e.path());
  REQUIRE(dead.size() == 1);
  CHECK(dead[0].filename().string().starts_with(".killed.zip.rodfab-partial-" + std::to_string(killed) + "-"));
  CHECK_FALSE(inspectJob(dead[0]).ok());

  // A live writer in another process, holding its staging folder while this one writes.
  int toChild[2], toParent[2];
  REQUIRE(::pipe(toChild) == 0);
  REQUIRE(::pipe(toParent) == 0);
  const pid_t live = ::fork();
  REQUIRE(live >= 0);
  if (live == 0) {
    JobWriter writer(specFor(*grid, dir / "live.zip"));
    char c = 'r';
    if (::write(toParent[1], &c, 1) != 1 || ::read(toChild[0], &c, 1) != 1) ::_exit(2);
    for (int k = 3; k < 27; k += 8) writer.addBand({band(*grid, k, std::min(k + 8, 27)), nullptr, k, std::min(k + 8, 27)});
    writer.finalize();
    ::_exit(0);
  }
  char c = 0;
  REQUIRE(::read(toParent[0], &c, 1) == 1);
  // Strangers: names that only look like ours, a lock-less folder of a live pid (ours), a held lock.
  fs::create_directories(dir / ".notes.rodfab-partial-abc");
  fs::create_directories(dir / ".x.zip.rodfab-partial-" / "keep");
  fs::create_directories(dir / ("..rodfab-partial-" + std::to_string(killed) + "-0"));
  fs::create_directories(dir / (".mine.zip.rodfab-partial-" + std::to_string(::getpid()) + "-7"));
  writeAll(dir / ".user.rodfab-partial-1-2.txt", Bytes{'u'});
  const std::set<std::string> strangers = {".notes.rodfab-partial-abc", ".x.zip.rodfab-partial-",
                                           "..rodfab-partial-" + std::to_string(killed) + "-0",
                                           ".mine.zip.rodfab-partial-" + std::to_string(::getpid()) + "-7",
                                           ".user.rodfab-partial-1-2.txt"};
  // An older version's lock-less folder of a dead pid goes.
  fs::create_directories(dir / (".old.zip.rodfab-partial-" + std::to_string(killed) + "-3") / "previews");

  writeJob(*grid, specFor(*grid, dir / "other.zip"), 24);  // another target name in the same folder
  std::set<std::string> left;
  for (const auto& e : fs::directory_iterator(dir)) left.insert(e.path().filename().string());
  for (const std::string& s : strangers) CHECK(left.contains(s));
  CHECK(left.contains("other.zip"));
  CHECK_FALSE(left.contains(dead[0].filename().string()));
  CHECK(std::count_if(left.begin(), left.end(), [&](const std::string& n) { return n.starts_with(".live.zip.rodfab-partial-"); }) == 1);
  CHECK(left.size() == strangers.size() + 2);  // + other.zip + the live writer's staging folder

  REQUIRE(::write(toChild[1], &c, 1) == 1);  // the live writer finishes its job undisturbed
  ::waitpid(live, &status, 0);
  CHECK((WIFEXITED(status) && WEXITSTATUS(status) == 0));
  CHECK((decodeJob(dir / "live.zip") == gridVoxels(*grid)));
  for (int fd : {toChild[0], toChild[1], toParent[0], toParent[1]}) ::close(fd);
}

TEST_CASE("Moduli beyond the float range, infinite or NaN neither crash the previews nor stay behind", "[job][previews]") {
  const fs::path dir = scratch("hostile-moduli");
  const auto grid = overhangPart(28);
  auto modulus = openvdb::FloatGrid::create(std::numeric_limits<float>::quiet_NaN());
  modulus->setTransform(rodfab::test::profileTransform(connex3(), kOrigin));
  const float hostile[] = {std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                           std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::max(),
                           std::numeric_limits<float>::denorm_min(), 0.0f, -5.0f};
  auto acc = modulus->getAccessor();
  std::size_t n = 0;
  for (auto it = grid->cbeginValueOn(); it; ++it, ++n)  // finite moduli on one side, hostile ones on the other
    acc.setValue(it.getCoord(), it.getCoord().x() < 12 ? 10.0f + it.getCoord().z() : hostile[n % std::size(hostile)]);
  for (const bool onlyHostile : {false, true}) {
    INFO((onlyHostile ? "no finite modulus at all" : "finite and hostile moduli mixed"));
    if (onlyHostile)
      for (auto it = modulus->beginValueOn(); it; ++it)
        if (std::isfinite(*it) && *it > 0.0f) it.setValue(std::numeric_limits<float>::infinity());
    const fs::path job = dir / (onlyHostile ? "hostile.zip" : "mixed.zip");
    {
      JobWriter writer(specFor(*grid, job));
      for (int k = 3; k < 27; k += 8) writer.addBand({band(*grid, k, std::min(k + 8, 27)), modulus, k, std::min(k + 8, 27)});
      writer.finalize();
    }
    CHECK(inspectJob(job).ok());
    CHECK((decodeJob(job) == gridVoxels(*grid)));
    const auto files = openJobFiles(job);
    CHECK(files->contains("previews/projections-modulus.png") == !onlyHostile);
    if (onlyHostile) continue;
    // Off-scale moduli are drawn grey (r = g = b), finite ones on the colour ramp (r, g, b differ).
    const RgbImage preview = decodePngRgb(files->read("previews/projections-modulus.png"));
    bool grey = false, coloured = false;
    for (int y = 0; y < preview.height; ++y)
      for (int x = 0; x < preview.width; ++x) {
        const std::uint8_t* p = preview.at(x, y);
        const bool background = p[0] == 196 && p[1] == 204 && p[2] == 216;
        if (p[0] == p[1] && p[1] == p[2] && p[0] > 60 && p[0] < 140) grey = true;
        if (!background && (p[0] != p[1] || p[1] != p[2]) && p[2] < 100 && p[0] > 150) coloured = true;  // the ramp's yellow end
      }
    CHECK(grey);
    CHECK(coloured);
  }
  CHECK(std::distance(fs::directory_iterator(dir), fs::directory_iterator()) == 2);
}

TEST_CASE("Preview views keep only the cells their pixels show", "[job][previews]") {
  SECTION("the axis sampling: every pixel's cell is kept, nothing else") {
    for (const auto& [cells, pixels] : {std::pair{2000, 485}, std::pair{9456, 1273}, std::pair{7, 300}, std::pair{1, 1}}) {
      const AxisSamples axis(cells, pixels);
      std::set<int> shown;
      for (int p = 0; p < pixels; ++p) {
        // The pixel's centre, mapped onto the cells, lies in the cell it shows.
        const int c = axis.cellOfPixel(p);
        CHECK(c == std::min(cells - 1, static_cast<int>(std::floor((p + 0.5) * cells / pixels))));
        shown.insert(c);
      }
      CHECK(axis.kept() == static_cast<int>(shown.size()));
      for (int c = 0; c < cells; ++c) {
        const bool hidden = (axis.hiddenMask()[static_cast<std::size_t>(c / 8)] >> (7 - c % 8)) & 1;
        CHECK((axis.slot(c) >= 0) == shown.contains(c));
        CHECK(hidden == !shown.contains(c));
      }
    }
  }
  SECTION("a 400 x 40 x 150 mm coupon plate's views fit in a few MB, not 564 MB") {
    JobGeometry g;
    g.width = 9456, g.height = 473, g.layers = 5000;  // 400 x 40 x 150 mm of Connex3 voxels
    const Previews previews(g, connex3(), 16);
    const std::size_t fullResolution = 9 * (std::size_t{9456} * 473 + std::size_t{9456} * 5000 + std::size_t{473} * 5000);
    CHECK(fullResolution > 400'000'000);
    CHECK(previews.memoryBytes() < 8'000'000);
  }
}
