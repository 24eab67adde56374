// `inspect` as a security boundary: real jobs made by the writer, then damaged or made hostile with
// other code than the reader's (libzip to rebuild archives, a hand-written zip encoder for headers that
// lie, zlib for deflate bombs, POSIX calls for FIFOs and links), must be refused with located findings,
// in bounded time and memory, never crashing, hanging or reading anything outside the job. Helpers:
// tests/inspect_fixture.hpp.
#include "tests/inspect_fixture.hpp"

#include <catch2/catch.hpp>
#include <openssl/evp.h>

#include <sys/stat.h>

#include <string>

using namespace rodfab::test;

TEST_CASE("Entries declaring or expanding to more than their image can hold are refused unread, in bounded memory",
          "[inspect][hostile]") {
  const fs::path dir = scratch("bombs");
  writeSmallJob(dir / "job.zip");
  const auto files = unzip(dir / "job.zip");
  const std::string layer = "VeroWhitePlus_0002.bmp";
  const double before = peakRssMiB();

  SECTION("an entry declaring 3.75 GiB") {
    auto raw = rawEntries(files);
    for (RawEntry& e : raw)
      if (e.name == layer) e.size = 0xF0000000u;
    writeRawZip(dir / "huge.zip", raw);
    CHECK(hasDefect(inspectJob(dir / "huge.zip"), "huge.zip: " + layer + ": declares 4026531840 bytes"));
  }
  SECTION("a deflate bomb whose headers tell the truth") {
    const std::uint64_t size = 256ull << 20;
    auto raw = rawEntries(files);
    for (RawEntry& e : raw)
      if (e.name == layer) {
        e.stored = deflateRaw(size);
        e.compressedSize = static_cast<std::uint32_t>(e.stored.size());
        e.size = static_cast<std::uint32_t>(size);
        e.crc = crcOfZeros(size);
      }
    writeRawZip(dir / "bomb.zip", raw);
    CHECK(hasDefect(inspectJob(dir / "bomb.zip"), layer + ": declares 268435456 bytes"));
  }
  SECTION("a deflate bomb whose headers lie about its size") {
    auto raw = rawEntries(files);
    for (RawEntry& e : raw)
      if (e.name == layer) {
        e.stored = deflateRaw(256ull << 20);  // the header keeps the true image's size and CRC
        e.compressedSize = static_cast<std::uint32_t>(e.stored.size());
      }
    writeRawZip(dir / "liar.zip", raw);
    const InspectReport report = inspectJob(dir / "liar.zip");
    CHECK(hasDefect(report, "liar.zip: " + layer + ": expands to more than"));
  }
  SECTION("a deflate bomb listed in the manifest with its true checksum") {
    const std::uint64_t size = 256ull << 20;  // tests/cli/printer_profiles.sh measures a 1.2 GB one
    unsigned char digest[32];
    {
      const Bytes zeros(1 << 20, 0);
      EVP_MD_CTX* ctx = EVP_MD_CTX_new();
      EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr);
      for (std::uint64_t n = 0; n < size >> 20; ++n) EVP_DigestUpdate(ctx, zeros.data(), zeros.size());
      unsigned int length = 0;
      EVP_DigestFinal_ex(ctx, digest, &length);
      EVP_MD_CTX_free(ctx);
    }
    char hex[65];
    for (int i = 0; i < 32; ++i) std::snprintf(hex + 2 * i, 3, "%02x", digest[i]);
    auto raw = rawEntries(tampered(files, [&](json& m) { m["files"]["bomb.bin"] = {{"bytes", size}, {"sha256", std::string(hex, 64)}}; }));
    RawEntry bomb{"bomb.bin", deflateRaw(size)};
    bomb.compressedSize = static_cast<std::uint32_t>(bomb.stored.size());
    bomb.size = static_cast<std::uint32_t>(size);
    bomb.crc = crcOfZeros(size);
    raw.push_back(bomb);
    writeRawZip(dir / "listed-bomb.zip", raw);
    CHECK(fs::file_size(dir / "listed-bomb.zip") < (1u << 20));
    const InspectReport report = inspectJob(dir / "listed-bomb.zip");
    CHECK(hasDefect(report, "listed-bomb.zip: bomb.bin: unexpected entry"));
    CHECK(hasDefect(report, "manifest.json: files: lists bomb.bin, which is not part of the job"));
  }
  // The bombs were never inflated: inspecting grew this process by far less than any of them.
  CHECK(peakRssMiB() - before < 100.0);
}

TEST_CASE("Entry names unsafe on some platform are refused even when the manifest lists them", "[inspect][hostile]") {
  const fs::path dir = scratch("names");
  writeSmallJob(dir / "job.zip");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"../../x", "'..' component"},
      {"previews/../../x", "'..' component"},
      {"/etc/x", "absolute path"},
      {"C:/x", "':'"},
      {"a\\b", "backslash"},
      {"previews/con.txt", "Windows device"},
      {"bell\a.bmp", "control character"},
      {std::string("caf\xc3\xa9.bmp"), "not printable ASCII"},
      {"trailing./x", "ending in a dot"},
      {"a//b", "empty path component"},
      {"what?.bmp", "Windows refuses"},
  };
  for (const auto& [name, why] : cases) {
    auto files = unzip(dir / "job.zip");
    addListed(files, name, bytesOf("listed, with its true checksum"));
    auto raw = rawEntries(files);
    writeRawZip(dir / "unsafe.zip", raw);
    const InspectReport report = inspectJob(dir / "unsafe.zip");
    INFO(name);
    CHECK_FALSE(report.ok());
    CHECK(hasDefect(report, "unsafe entry name"));
    CHECK(hasDefect(report, why));
    for (const std::string& d : report.defects)  // names are shown escaped
      CHECK(std::all_of(d.begin(), d.end(), [](char c) { return c >= 0x20 && c < 0x7f; }));
  }
  SECTION("names equal but for letter case") {
    auto files = unzip(dir / "job.zip");
    addListed(files, "Previews/Contact-Sheet.png", bytesOf("x"));
    writeRawZip(dir / "case.zip", rawEntries(files));
    CHECK(hasDefect(inspectJob(dir / "case.zip"), "case.zip: Previews/Contact-Sheet.png: differs from previews/contact-sheet.png only in letter case"));
  }
  SECTION("a name twice") {
    auto raw = rawEntries(unzip(dir / "job.zip"));
    raw.push_back(raw[1]);  // build.txt again
    writeRawZip(dir / "twice.zip", raw);
    CHECK(hasDefect(inspectJob(dir / "twice.zip"), "twice.zip: holds two entries of the same name"));
  }
  SECTION("a symbolic link stored in the archive") {
    auto raw = rawEntries(unzip(dir / "job.zip"));
    raw[1].mode = 0120777;  // build.txt as a link
    writeRawZip(dir / "link.zip", raw);
    CHECK(hasDefect(inspectJob(dir / "link.zip"), "build.txt: is a symbolic link (Unix mode in the archive)"));
  }
}

TEST_CASE("The job's complete layout is checked against the profile", "[inspect][hostile]") {
  const fs::path dir = scratch("layout");
  writeSmallJob(dir / "job.zip");
  const auto original = unzip(dir / "job.zip");

  SECTION("a job without its build file, also dropped from the manifest") {
    auto files = original;
    std::erase_if(files, [](const auto& f) { return f.first == "build.txt"; });
    rezip(dir / "t.zip", tampered(files, [](json& m) { m["files"].erase("build.txt"); }));
    const InspectReport report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "t.zip: build.txt: missing"));
    CHECK(hasDefect(report, "manifest.json: files: lacks build.txt"));
  }
  SECTION("every image of one material removed, with every mention of it in the manifest") {
    auto files = original;
    std::erase_if(files, [](const auto& f) { return f.first.starts_with("TangoBlackPlus_"); });
    rezip(dir / "t.zip", tampered(files, [](json& m) {
            for (auto it = m["files"].begin(); it != m["files"].end();)
              it = it.key().starts_with("TangoBlackPlus_") ? m["files"].erase(it) : std::next(it);
            m["materials"].erase(1);
            for (json& l : m["layers"]) {
              l["files"].erase("TangoBlackPlus");
              l["voxels"].erase("TangoBlackPlus");
            }
            m["orientation_check"].erase("TangoBlackPlus");
          }));
    const InspectReport report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "every TangoBlackPlus image is missing (4 layers)"));
    CHECK(hasDefect(report, "manifest.json: materials: lists 1 materials"));
  }
  SECTION("a layer more in the manifest than in the images") {
    rezip(dir / "t.zip", tampered(original, [](json& m) { m["layer_count"] = 5; }));
    const InspectReport report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "VeroWhitePlus_0004.bmp: missing"));
    CHECK(hasDefect(report, "manifest.json: layers: lists 4 layers; layer_count is 5"));
  }
  SECTION("counts the images cannot hold, and an orientation count that is not the images'") {
    // A lie in the orientation record's count made inspect skip the check that finds flipped images.
    rezip(dir / "t.zip", tampered(original, [](json& m) {
            m["layers"][0]["voxels"]["VeroWhitePlus"] = std::uint64_t{1} << 40;
            m["orientation_check"]["TangoBlackPlus"]["voxels"] = m["orientation_check"]["TangoBlackPlus"]["voxels"].get<std::uint64_t>() + 1;
          }));
    const InspectReport report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "manifest.json: layers[0].voxels.VeroWhitePlus: 1099511627776 voxels, more than a layer's"));
    CHECK(hasDefect(report, "TangoBlackPlus: the manifest's orientation check counts"));
  }
  SECTION("an extra file, listed or not") {
    auto files = original;
    addListed(files, "notes.txt", bytesOf("hello"));
    files.emplace_back("previews/extra.png", bytesOf("not listed"));
    rezip(dir / "t.zip", files);
    const InspectReport report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "t.zip: notes.txt: unexpected entry"));
    CHECK(hasDefect(report, "t.zip: previews/extra.png: unexpected entry"));
  }
}

TEST_CASE("The fields restating the profile, describing the images and recording the calibration are checked", "[inspect][hostile]") {
  const fs::path dir = scratch("descriptions");
  writeSmallJob(dir / "job.zip");
  const auto original = unzip(dir / "job.zip");
  // Nothing in the images depends on them, but a reader of the manifest alone takes them at their word.
  rezip(dir / "t.zip", tampered(original, [](json& m) {
          m["image"]["x_pixels_per_metre"] = "abc";
          m["image"]["y_pixels_per_metre"] = 23621;  // near 600 dpi's 23622, on the Connex3's 300 dpi axis
          m["image"]["origin"] = "bottom-left";
          m["image"]["row_order"] = 5;
          m["profile"]["printer"] = "Evil Printer";
          m["profile"]["tray_mm"] = {0, 390, 200};
          m["profile"]["layer_thickness_mm"] = 0.1;
          m["dithering"]["ditherer"] = "White Noise\n";
          m["calibration"] = {{"file", "cal.json"}, {"sha256", "zz"}, {"materials", 3}, {"warning", nullptr}};
        }));
  const InspectReport report = inspectJob(dir / "t.zip");
  CHECK(hasDefect(report, "manifest.json: image.x_pixels_per_metre: expected an integer in [1, 1000000000], got \"abc\""));
  CHECK(hasDefect(report, "manifest.json: image.y_pixels_per_metre: expected 11811 (300 dpi)"));
  CHECK(hasDefect(report, "manifest.json: image.origin: expected \"top-left\""));
  CHECK(hasDefect(report, "manifest.json: image.row_order: expected a string, got 5"));
  CHECK(hasDefect(report, "manifest.json: profile.printer: expected \"Stratasys Objet500 Connex3\""));
  CHECK(hasDefect(report, "manifest.json: profile.tray_mm[0]: expected 490 mm"));
  CHECK(hasDefect(report, "manifest.json: profile.layer_thickness_mm: expected"));
  CHECK(hasDefect(report, "manifest.json: dithering.ditherer: expected up to 64 lowercase letters, digits and '-'"));
  CHECK(hasDefect(report, "manifest.json: calibration.sha256: expected 64 lowercase hexadecimal digits, got \"zz\""));
  CHECK(hasDefect(report, "manifest.json: calibration.materials: expected an object or null, got 3"));
  CHECK(report.defects.size() == 10);  // the tray's other two axes agree; nothing else is wrong
}

TEST_CASE("The manifest's image size, nesting and value types are checked", "[inspect][hostile]") {
  const fs::path dir = scratch("manifest-values");
  writeSmallJob(dir / "job.zip");
  const auto original = unzip(dir / "job.zip");

  SECTION("images larger than the tray") {
    rezip(dir / "t.zip", tampered(original, [](json& m) { m["image"]["width"] = 1 << 20; }));
    CHECK(hasDefect(inspectJob(dir / "t.zip"), "manifest.json: image.width: expected an integer in [32, 11552]"));
  }
  SECTION("a manifest nested 60,000 levels deep, or holding millions of values") {
    auto files = original;
    for (auto& [name, data] : files)
      if (name == "manifest.json") data = bytesOf(std::string(60000, '[') + std::string(60000, ']'));
    rezip(dir / "t.zip", files);
    CHECK(hasDefect(inspectJob(dir / "t.zip"), "t.zip: manifest.json: cannot be read: nested deeper than 64 arrays and objects at line 1, column 65"));
    for (auto& [name, data] : files)
      if (name == "manifest.json") {
        std::string many = "[0";
        for (int n = 0; n < 2000000; ++n) many += ",0";
        data = bytesOf(many + "]");
      }
    rezip(dir / "t.zip", files);
    // Read in bounded memory either way; more values than any bundled profile's job has leave the job
    // not checked without its profile (a profile file's job may have more layers), a defect with it.
    CHECK_THAT(inspectJob(dir / "t.zip").notChecked, Catch::StartsWith("its manifest.json holds more than"));
    InspectOptions withProfile;
    withProfile.profile = connex3();
    CHECK(hasDefect(inspectJob(dir / "t.zip", withProfile), "manifest.json: cannot be read: the document holds more than"));
  }
  SECTION("manifest values of the wrong type are described, not serialized") {
    json deep = json::array();
    for (int n = 0; n < 50; ++n) deep = json::array({deep});
    const auto wrongTypes = [&](json& m) {
      m["frame"]["origin_mm"] = deep;
      m["dithering"]["seed"] = "\x1b[31mred";
    };
    rezip(dir / "t.zip", tampered(original, wrongTypes));
    InspectReport report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "manifest.json: frame.origin_mm: expected an array of three finite numbers, got an array"));
    CHECK(hasDefect(report, "manifest.json: dithering.seed: expected a whole number >= 0, got \"\\x1b[31mred\""));
    rezip(dir / "t.zip", tampered(original, [&](json& m) {
            wrongTypes(m);
            m["image"]["format"] = deep;
          }));
    report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "manifest.json: image.format: expected a string, got an array"));
  }
}

TEST_CASE("Folder jobs: links, FIFOs and devices are never opened, and inspect never hangs", "[inspect][hostile]") {
  const fs::path dir = scratch("folder");
  const HangGuard guard(60);
  const auto fresh = [&](const std::string& name) {
    writeSmallJob(dir / name, {ArchiveFormat::Directory, ImageFormat::Png});
    return dir / name;
  };
  SECTION("a FIFO in place of a layer") {
    const fs::path job = fresh("fifo");
    fs::remove(job / "VeroWhitePlus_0001.png");
    REQUIRE(::mkfifo((job / "VeroWhitePlus_0001.png").c_str(), 0644) == 0);
    CHECK(hasDefect(inspectJob(job), "fifo: VeroWhitePlus_0001.png: is a FIFO (named pipe)"));
  }
  SECTION("a link to /dev/zero in place of a layer, and the manifest a link to /dev/stdin") {
    const fs::path job = fresh("links");
    fs::remove(job / "VeroWhitePlus_0001.png");
    fs::create_symlink("/dev/zero", job / "VeroWhitePlus_0001.png");
    CHECK(hasDefect(inspectJob(job), "links: VeroWhitePlus_0001.png: is a symbolic link"));
    fs::remove(job / "manifest.json");
    fs::create_symlink("/dev/stdin", job / "manifest.json");
    CHECK(hasDefect(inspectJob(job), "links: manifest.json: is a symbolic link"));
  }
  SECTION("the previews folder a link to /dev, an extra FIFO, a deeper folder") {
    const fs::path job = fresh("folders");
    fs::remove_all(job / "previews");
    fs::create_directory_symlink("/dev", job / "previews");
    REQUIRE(::mkfifo((job / "extra").c_str(), 0644) == 0);
    fs::create_directories(job / "deep" / "deeper" / "deepest");
    const InspectReport report = inspectJob(job);
    CHECK(hasDefect(report, "folders: previews: is a symbolic link"));
    CHECK(hasDefect(report, "folders: extra: is a FIFO"));
    CHECK(hasDefect(report, "folders: deep/: unexpected folder"));
    CHECK(hasDefect(report, "folders: previews/contact-sheet.png: missing"));
  }
  SECTION("the job itself a FIFO or a device") {
    REQUIRE(::mkfifo((dir / "job.zip").c_str(), 0644) == 0);
    CHECK(hasDefect(inspectJob(dir / "job.zip"), "job.zip: is a FIFO (named pipe), not a job"));
    CHECK(hasDefect(inspectJob("/dev/zero"), "/dev/zero: is a character device, not a job"));
  }
}
