// printer_profiles/ jobs: written from synthetic grids, then decoded back from their files and compared
// voxel for voxel; support, thread and band independence, tampering, grids the writer refuses, tiles
// and previews. Replacing, atomicity, interrupts and staging folders: test_printer_jobs_commit.cpp.
// Profiles, bitmaps and the layout: tests/test_printer_profiles.cpp.
#include "printer_profiles/leaf_bits.hpp"  // internal: a leaf's bits as image rows
#include "printer_profiles/job_manifest.hpp"  // internal: a layer's moments
#include "printer_profiles/previews.hpp"  // internal: the views' memory
#include "common/xxh128.hpp"
#include "tests/printer_jobs_fixture.hpp"

#include <catch2/catch.hpp>
#include <tbb/global_control.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <stdexcept>
#include <tuple>

using namespace rodfab::test;

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

  // Nor on where the layers' zip forms wait for the zip: all in memory (above), all in the staging
  // folder's file, or the first few kB in memory and the rest in the file.
  for (const std::uint64_t inMemory : {std::uint64_t{0}, std::uint64_t{5000}}) {
    const fs::path folder = dir / ("in-memory-" + std::to_string(inMemory));
    fs::create_directories(folder);
    JobSpec spec = specFor(*grid, folder / "job.zip");
    spec.options.zipFormsInMemory = inMemory;
    writeJob(*grid, spec, 3);
    CHECK((readAll(folder / "job.zip") == a));
  }
}

TEST_CASE("A band's layer images hold only its own voxels: what the layer before in the same bitmaps wrote is cleared", "[job]") {
  // Two bands of 8 layers whose footprints share no row and no byte: the second band's layers are
  // written into the bitmaps the first band's used (the writer keeps them from band to band, clearing
  // only the words the last layer wrote). Each image must be the BMP encodeBmp makes of a bitmap filled
  // from scratch with that layer's voxels.
  const fs::path dir = scratch("two-bands");
  auto grid = newGrid();
  auto acc = grid->getAccessor();
  std::mt19937 rng(5);
  std::bernoulli_distribution vero(0.5);
  for (int k = 0; k < 16; ++k) {
    const bool first = k < 8;
    for (int j = first ? 0 : 20; j < (first ? 10 : 30); ++j)
      for (int i = first ? 0 : 48; i < (first ? 40 : 96); ++i) acc.setValueOn({i, j, k}, vero(rng));
  }
  const JobResult result = writeJob(*grid, specFor(*grid, dir / "job.zip"), 8);
  const JobGeometry& g = result.geometry;
  REQUIRE(g.layers == 16);
  const auto files = openJobFiles(dir / "job.zip");
  const Bytes text = files->read("manifest.json");
  const json manifest = json::parse(text.begin(), text.end());
  std::map<std::string, bool> rigidFiles;  // material name -> whether it is the rigid one
  for (const json& m : manifest["materials"]) rigidFiles[m["name"]] = m["role"] == "rigid";
  int compared = 0;
  for (const json& layer : manifest["layers"]) {
    const int k = g.k(layer["layer"].get<int>());
    for (const auto& [material, file] : layer["files"].items()) {
      Bitmap expected(g.width, g.height);
      for (int r = 0; r < g.height; ++r)
        for (int c = 0; c < g.width; ++c) {
          bool value = false;
          if (grid->tree().probeValue({g.i(c), g.j(r), k}, value) && value == rigidFiles.at(material)) expected.set(c, r);
        }
      INFO("layer k = " << k << ", " << material);
      CHECK((files->read(file.get<std::string>()) == encodeBmp(expected, connex3().xDpi, connex3().yDpi)));
      ++compared;
    }
  }
  CHECK(compared == 32);
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
  // The ditherer's label is one inspect accepts: lowercase letters, digits and '-', up to 64 of them.
  for (const std::string& label : std::vector<std::string>{"White", "white noise", "white\x1b[31m", std::string(65, 'a')}) {
    JobSpec badLabel = specFor(*grid, dir / "bad-label");
    badLabel.metadata.ditherer = label;
    CHECK_THROWS_WITH(JobWriter(badLabel), Catch::Contains("is not a label of up to 64 lowercase letters, digits and '-'"));
  }
  JobSpec badCalibration = specFor(*grid, dir / "bad-label");
  badCalibration.metadata.calibration = CalibrationRecord{"cal.json", "ZZ", "", "", ""};
  CHECK_THROWS_WITH(JobWriter(badCalibration), Catch::Contains("SHA-256 \"ZZ\" is not 64 lowercase hexadecimal digits"));
  CHECK(!fs::exists(dir / "bad-label"));
  CHECK(isDithererLabel("error-diffusion"));
  CHECK(isDithererLabel(""));  // not said
  CHECK(isDithererLabel(std::string(64, 'a')));
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
  const InspectReport report = inspectJob(dir / "tiles.zip");  // every layer decoded: its counts against the manifest's
  CHECK(report.ok());
  REQUIRE(report.materials.size() == 2);
  CHECK(report.materials[0].voxels + report.materials[1].voxels == expected.size());
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
  SECTION("previewMemoryBytes says, before the job, what the views and tiles come to hold") {
    // Axes with fewer cells than pixels and more; contact sheets of one layer, several, more than the job has.
    for (const auto& [w, h, layers, sheet] : {std::tuple{40, 30, 20, 6}, std::tuple{3000, 200, 900, 16}, std::tuple{9456, 473, 60, 100},
                                             std::tuple{8, 8, 1, 1}}) {
      JobGeometry g;
      g.width = w, g.height = h, g.layers = layers;
      Previews previews(g, connex3(), sheet);
      const LayerBitmaps empty(w, h, connex3().xDpi, connex3().yDpi);
      for (const int layer : previews.contactLayers()) previews.addLayer(layer, empty, nullptr);  // fills the tiles
      CHECK(previewMemoryBytes(g, connex3(), sheet) == previews.memoryBytes());
    }
    // A sheet of no layers is a sheet of one, as the writer draws it.
    JobGeometry g;
    g.width = 40, g.height = 30, g.layers = 20;
    CHECK(previewMemoryBytes(g, connex3(), 0) == previewMemoryBytes(g, connex3(), 1));
    // Nothing to preview: refused, not a figure from undefined arithmetic.
    for (const auto& [w, h, layers] : {std::tuple{0, 30, 20}, std::tuple{40, 0, 20}, std::tuple{40, 30, 0}, std::tuple{-8, 30, 20}}) {
      g.width = w, g.height = h, g.layers = layers;
      CHECK_THROWS_AS(previewMemoryBytes(g, connex3(), 16), std::invalid_argument);
    }
  }
}

TEST_CASE("A leaf's image rows hold the voxels OpenVDB says are on", "[job][leaf]") {
  // The truth is OpenVDB's own isValueOn, not the bit layout the writer assumes.
  std::mt19937 random(7);
  for (int trial = 0; trial < 200; ++trial) {
    openvdb::BoolTree::LeafNodeType leaf(openvdb::Coord(0), false);
    const int density = trial % 4;  // sparse to full
    for (openvdb::Index n = 0; n < openvdb::BoolTree::LeafNodeType::SIZE; ++n)
      if (static_cast<int>(random() % 4) < density || trial == 0) leaf.setValueOn(n, true);
    const LeafRows rows(maskBytes(leaf.getValueMask()));
    for (int z = 0; z < 8; ++z)
      for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
          const bool bit = (rows.row(y, z) >> (7 - x)) & 1;
          REQUIRE(bit == leaf.isValueOn(openvdb::Coord(x, y, z)));
        }
  }
}

TEST_CASE("A leaf's 8 rows add the moments of their voxels", "[job][leaf]") {
  // Moments::addRows counts bits under masks; the truth here is every voxel's own coordinates.
  std::mt19937_64 random(11);
  std::vector<std::uint64_t> cases{0, ~std::uint64_t{0}, 1, std::uint64_t{1} << 63, 0x80, 0x0100000000000000u};
  for (int n = 0; n < 2000; ++n) cases.push_back(random() & random() & (n % 2 ? random() : ~std::uint64_t{0}));
  for (const std::uint64_t rows : cases) {
    const int firstI = -40 + static_cast<int>(random() % 80) * 8, firstJ = -24 + static_cast<int>(random() % 48), k = static_cast<int>(random() % 50);
    Moments fast, truth;
    fast.addRows(rows, firstI, firstJ, k);
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        if ((rows >> (8 * y + 7 - x)) & 1) {  // x = 0 in bit 7 of row y's byte
          const openvdb::Coord c(firstI + x, firstJ + y, k);
          ++truth.count;
          for (int a = 0; a < 3; ++a) truth.sum[a] += c[a];
          truth.min.minComponent(c);
          truth.max.maxComponent(c);
        }
    REQUIRE(fast.count == truth.count);
    for (int a = 0; a < 3; ++a) REQUIRE(fast.sum[a] == truth.sum[a]);
    REQUIRE(fast.min == truth.min);
    REQUIRE(fast.max == truth.max);
  }
}
