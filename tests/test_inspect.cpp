// `inspect` as a security boundary: real jobs made by the writer, then damaged or made hostile with
// other code than the reader's (libzip to rebuild archives, a hand-written zip encoder for headers that
// lie, zlib for deflate bombs, POSIX calls for FIFOs and links), must be refused with located findings,
// in bounded time and memory, never crashing, hanging or reading anything outside the job.
#include "common/sha256.hpp"
#include "common/xxh128.hpp"
#include "printer_profiles/printer_profiles.hpp"
#include "tests/printer_profiles_fixture.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <openssl/evp.h>
#include <zip.h>
#include <zlib.h>

#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <csignal>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <stdexcept>

using namespace rodfab::printer_profiles;
namespace fs = std::filesystem;
using nlohmann::json;
using rodfab::common::sha256Hex;
using rodfab::common::xxh128Hex;
using rodfab::test::connex3;
using rodfab::test::scratch;
using rodfab::test::writeAll;

namespace {

struct SmallJob {
  ArchiveFormat archive = ArchiveFormat::Zip;
  ImageFormat image = ImageFormat::Bmp;
  SupportPolicy support = SupportPolicy::Printer;
  const Profile* profile = nullptr;  // default: the bundled Connex3
  bool verify = true;                // the writer's own inspection
  int layers = 4;
};

// A 10 x 6 x `layers`-voxel block of random Vero and Tango, written by the JobWriter.
void writeSmallJob(const fs::path& output, const SmallJob& job = {}) {
  openvdb::initialize();
  const Profile& profile = job.profile ? *job.profile : connex3();
  const openvdb::Vec3d origin(1.0, 2.0, 0.0);
  auto grid = openvdb::BoolGrid::create(false);
  grid->setTransform(rodfab::test::profileTransform(profile, origin));
  auto acc = grid->getAccessor();
  std::mt19937 rng(5);
  for (int k = 0; k < job.layers; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 10; ++i) acc.setValueOn({i, j, k}, rng() % 2 == 0);
  JobSpec spec;
  spec.profile = profile;
  spec.partBounds = grid->evalActiveVoxelBoundingBox();
  spec.originMm = origin;
  spec.metadata.ditherer = "white";
  spec.options.output = output;
  spec.options.archive = job.archive;
  spec.options.imageFormat = job.image;
  spec.options.support = job.support;
  spec.options.verify = job.verify;
  if (job.support == SupportPolicy::Explicit) {
    auto tops = std::make_shared<ColumnTops>(planJob(profile, spec.partBounds));
    tops->include(*grid);
    spec.supportTops = tops;
  }
  JobWriter writer(std::move(spec));
  writer.addBand({grid, nullptr, 0, job.layers});
  writer.finalize();
}

Bytes bytesOf(const std::string& s) { return Bytes(s.begin(), s.end()); }

// Every entry of a zip, in order, read with libzip directly.
std::vector<std::pair<std::string, Bytes>> unzip(const fs::path& file) {
  int error = 0;
  zip_t* za = zip_open(file.c_str(), ZIP_RDONLY, &error);
  REQUIRE(za);
  std::vector<std::pair<std::string, Bytes>> out;
  for (zip_int64_t n = 0; n < zip_get_num_entries(za, 0); ++n) {
    zip_stat_t st;
    REQUIRE(zip_stat_index(za, static_cast<zip_uint64_t>(n), 0, &st) == 0);
    Bytes data(st.size);
    zip_file_t* zf = zip_fopen_index(za, static_cast<zip_uint64_t>(n), 0);
    REQUIRE(zip_fread(zf, data.data(), data.size()) == static_cast<zip_int64_t>(data.size()));
    zip_fclose(zf);
    out.emplace_back(st.name, std::move(data));
  }
  zip_discard(za);
  return out;
}

// A new zip with these entries (libzip, deflated or stored).
void rezip(const fs::path& file, const std::vector<std::pair<std::string, Bytes>>& entries, bool store = false) {
  fs::remove(file);
  int error = 0;
  zip_t* za = zip_open(file.c_str(), ZIP_CREATE | ZIP_EXCL, &error);
  REQUIRE(za);
  for (const auto& [name, data] : entries) {
    zip_source_t* source = zip_source_buffer(za, data.data(), data.size(), 0);
    const zip_int64_t index = zip_file_add(za, name.c_str(), source, ZIP_FL_ENC_UTF_8);
    REQUIRE(index >= 0);
    if (store) REQUIRE(zip_set_file_compression(za, static_cast<zip_uint64_t>(index), ZIP_CM_STORE, 0) == 0);
    REQUIRE(zip_file_set_mtime(za, static_cast<zip_uint64_t>(index), static_cast<time_t>(kZipEntryTime), 0) == 0);
  }
  REQUIRE(zip_close(za) == 0);
}

// A zip encoder that writes whatever headers it is told: sizes, CRCs and Unix modes may lie.
struct RawEntry {
  std::string name;
  Bytes stored;             // the bytes as they sit in the archive (already deflated for method 8)
  std::uint16_t method = 8;
  std::uint32_t crc = 0, compressedSize = 0, size = 0;
  std::uint32_t mode = 0100644;
};

void put16(Bytes& b, std::uint32_t v) { b.insert(b.end(), {std::uint8_t(v), std::uint8_t(v >> 8)}); }
void put32(Bytes& b, std::uint32_t v) { b.insert(b.end(), {std::uint8_t(v), std::uint8_t(v >> 8), std::uint8_t(v >> 16), std::uint8_t(v >> 24)}); }

void writeRawZip(const fs::path& file, const std::vector<RawEntry>& entries) {
  Bytes out, central;
  for (const RawEntry& e : entries) {
    const auto offset = static_cast<std::uint32_t>(out.size());
    for (Bytes* b : {&out, &central}) {
      put32(*b, b == &out ? 0x04034b50 : 0x02014b50);
      if (b == &central) put16(*b, 0x031e);  // made by: Unix
      for (std::uint32_t v : {20u, 0u, std::uint32_t(e.method), 0u, 0x5021u}) put16(*b, v);
      for (std::uint32_t v : {e.crc, e.compressedSize, e.size}) put32(*b, v);
      put16(*b, static_cast<std::uint32_t>(e.name.size()));
      put16(*b, 0);
      if (b == &central) {
        for (int n = 0; n < 3; ++n) put16(*b, 0);  // comment, disk, internal attributes
        put32(*b, e.mode << 16);
        put32(*b, offset);
      }
      b->insert(b->end(), e.name.begin(), e.name.end());
      if (b == &out) b->insert(b->end(), e.stored.begin(), e.stored.end());
    }
  }
  const auto directory = static_cast<std::uint32_t>(out.size());
  out.insert(out.end(), central.begin(), central.end());
  put32(out, 0x06054b50);
  for (int n = 0; n < 2; ++n) put16(out, 0);
  for (int n = 0; n < 2; ++n) put16(out, static_cast<std::uint32_t>(entries.size()));
  put32(out, static_cast<std::uint32_t>(central.size()));
  put32(out, directory);
  put16(out, 0);
  writeAll(file, out);
}

// Raw deflate (zlib) of `size` zero bytes, or of `data` when given.
Bytes deflateRaw(std::uint64_t zeros, const Bytes* data = nullptr) {
  z_stream z{};
  REQUIRE(deflateInit2(&z, 9, Z_DEFLATED, -15, 9, Z_DEFAULT_STRATEGY) == Z_OK);
  Bytes out, in(data ? data->size() : std::min<std::uint64_t>(zeros, 1 << 20), 0);
  if (data) in = *data;
  std::uint64_t left = data ? data->size() : zeros;
  std::uint8_t buffer[1 << 16];
  int flush = Z_NO_FLUSH;
  do {
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(left, in.size()));
    left -= n;
    flush = left == 0 ? Z_FINISH : Z_NO_FLUSH;
    z.next_in = in.data();
    z.avail_in = static_cast<uInt>(n);
    do {
      z.next_out = buffer;
      z.avail_out = sizeof buffer;
      deflate(&z, flush);
      out.insert(out.end(), buffer, buffer + (sizeof buffer - z.avail_out));
    } while (z.avail_out == 0);
  } while (flush != Z_FINISH);
  deflateEnd(&z);
  return out;
}

std::uint32_t crcOfZeros(std::uint64_t size) {
  const Bytes zeros(1 << 20, 0);
  uLong crc = crc32(0, nullptr, 0);
  for (std::uint64_t left = size; left > 0;) {
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(left, zeros.size()));
    crc = crc32(crc, zeros.data(), static_cast<uInt>(n));
    left -= n;
  }
  return static_cast<std::uint32_t>(crc);
}

// A job's entries as honest raw entries (deflated or stored), so one of them can be made to lie.
std::vector<RawEntry> rawEntries(const std::vector<std::pair<std::string, Bytes>>& files, bool store = false) {
  std::vector<RawEntry> out;
  for (const auto& [name, data] : files) {
    RawEntry e{name, store ? data : deflateRaw(0, &data), std::uint16_t(store ? 0 : 8)};
    e.crc = static_cast<std::uint32_t>(crc32(0, data.data(), static_cast<uInt>(data.size())));
    e.compressedSize = static_cast<std::uint32_t>(e.stored.size());
    e.size = static_cast<std::uint32_t>(data.size());
    out.push_back(std::move(e));
  }
  return out;
}

const Bytes& entryBytes(const std::vector<std::pair<std::string, Bytes>>& files, const std::string& name) {
  for (const auto& [n, data] : files)
    if (n == name) return data;
  throw std::out_of_range("no entry " + name);
}

json manifestOf(const std::vector<std::pair<std::string, Bytes>>& files) {
  for (const auto& [name, data] : files)
    if (name == "manifest.json") return json::parse(data.begin(), data.end());
  FAIL("no manifest");
  return {};
}

void setManifest(std::vector<std::pair<std::string, Bytes>>& files, const json& manifest) {
  for (auto& [name, data] : files)
    if (name == "manifest.json") data = bytesOf(manifest.dump());
}

// Adds `name` to the job and lists it in the manifest with its true size and checksum.
void addListed(std::vector<std::pair<std::string, Bytes>>& files, const std::string& name, const Bytes& data) {
  json m = manifestOf(files);
  m["files"][name] = {{"bytes", data.size()}, {"xxh128", xxh128Hex(data)}};
  setManifest(files, m);
  files.emplace_back(name, data);
}

bool hasDefect(const InspectReport& report, const std::string& fragment) {
  for (const std::string& d : report.defects)
    if (d.find(fragment) != std::string::npos) return true;
  std::string all;
  for (const std::string& d : report.defects) all += "\n  " + d;
  UNSCOPED_INFO("no defect contains \"" << fragment << "\"; defects:" << all);
  return false;
}

// Peak resident memory of this process so far, in MiB.
double peakRssMiB() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

// Kills the test program if an inspection hangs (a FIFO opened for reading, /dev/stdin read).
struct HangGuard {
  explicit HangGuard(unsigned seconds) { ::alarm(seconds); }
  ~HangGuard() { ::alarm(0); }
};

}  // namespace

TEST_CASE("Valid small jobs of every form pass inspect", "[inspect]") {
  const fs::path dir = scratch("valid");
  writeSmallJob(dir / "bmp.zip");
  writeSmallJob(dir / "png", {ArchiveFormat::Directory, ImageFormat::Png, SupportPolicy::Explicit});
  for (const fs::path& job : {dir / "bmp.zip", dir / "png"}) {
    const InspectReport report = inspectJob(job);
    INFO(job << ": " << (report.defects.empty() ? "" : report.defects[0]));
    CHECK(report.ok());
    CHECK(report.layers == 4);
    CHECK(report.summary.profile == "stratasys-objet500-connex3");
  }
  CHECK(inspectJob(dir / "png").materials.size() == 3);
  CHECK(inspectJob(dir / "png").summary.supportPolicy == "explicit");
  // The same checks through the emitter's entry point.
  CHECK(inspectJobFiles(*openJobFiles(dir / "bmp.zip")).ok());
}

TEST_CASE("The writer's own check: a sample of layers decoded, the others read through their zip CRC-32", "[inspect]") {
  const fs::path dir = scratch("writer-check");
  const fs::path job = dir / "job.zip";
  writeSmallJob(job, {.layers = 40});
  InspectOptions writerCheck{connex3()};
  writerCheck.decodeEvery = 32;  // layers 0, 32 and 39 decoded
  writerCheck.zipCrcForSkippedLayers = true;
  REQUIRE(inspectJob(job, writerCheck).ok());
  const ProfileMaterial& rigid = connex3().material(MaterialRole::Rigid);
  const std::string skipped = connex3().layerFileName(rigid, 5, ImageFormat::Bmp);
  const std::string decoded = connex3().layerFileName(rigid, 32, ImageFormat::Bmp);
  const auto files = unzip(job);
  const auto damaged = [&](const std::string& name, bool relist) {
    auto out = files;
    for (auto& [n, data] : out)
      if (n == name) data[static_cast<std::size_t>(data[10])] ^= 0x80;  // the first pixel byte (bfOffBits < 256)
    if (relist)
      for (const auto& [n, data] : out)
        if (n == name) {
          json m = manifestOf(out);
          m["files"][name]["xxh128"] = xxh128Hex(data);
          setManifest(out, m);
        }
    return out;
  };

  SECTION("bytes that do not match the zip's CRC are found in a layer that is not decoded") {
    // The damaged image stored under the true image's CRC-32 and size.
    std::vector<RawEntry> raw = rawEntries(files);
    const auto changed = damaged(skipped, false);
    for (RawEntry& e : raw)
      for (const auto& [n, data] : changed)
        if (e.name == skipped && n == skipped) e.stored = deflateRaw(0, &data);
    for (RawEntry& e : raw) e.compressedSize = static_cast<std::uint32_t>(e.stored.size());
    writeRawZip(job, raw);
    CHECK(hasDefect(inspectJob(job, writerCheck), "CRC"));
    CHECK_FALSE(inspectJob(job).ok());
  }
  SECTION("a decoded layer's image is checked against the manifest's counts") {
    rezip(job, damaged(decoded, true));
    CHECK(hasDefect(inspectJob(job, writerCheck), "the manifest says"));
    CHECK(hasDefect(inspectJob(job), "the manifest says"));
  }
  SECTION("an image changed in a layer that is not decoded, with a fresh CRC, is only for inspect to find") {
    // The writer's mode trusts that the manifest's SHA-256 and the zip's CRC-32 were computed over the
    // same bytes (the writer does so); a job from elsewhere gets the full check.
    rezip(job, damaged(skipped, false));
    CHECK(inspectJob(job, writerCheck).ok());
    CHECK(hasDefect(inspectJob(job), "checksum mismatch"));
  }
}

TEST_CASE("The profile comes from the bundled ones by name or from the caller, never from a path in the manifest",
          "[inspect][hostile]") {
  const fs::path dir = scratch("profile-name");
  writeSmallJob(dir / "job.zip");
  auto files = unzip(dir / "job.zip");
  const HangGuard guard(60);
  for (const std::string name : {"/dev/stdin", "/dev/zero", "../../../../dev/zero", "stratasys-objet500-connex3.json", ""}) {
    json m = manifestOf(files);
    m["profile"]["name"] = name;
    setManifest(files, m);
    rezip(dir / "hostile.zip", files);
    const InspectReport report = inspectJob(dir / "hostile.zip");
    CHECK_FALSE(report.ok());
    CHECK(hasDefect(report, "hostile.zip: manifest.json: profile.name: \"" + name + "\" is not a bundled profile"));
  }

  // A job written for a profile file of another name passes only when that profile is given.
  Profile custom = connex3();
  custom.name = "my-connex3";
  // (The writer's own verification cannot know the profile until it passes it in InspectOptions.)
  writeSmallJob(dir / "custom.zip", {.profile = &custom, .verify = false});
  CHECK(hasDefect(inspectJob(dir / "custom.zip"), "\"my-connex3\" is not a bundled profile"));
  InspectOptions options;
  options.profile = custom;
  CHECK(inspectJob(dir / "custom.zip", options).ok());
  // ...and the bundled profile given explicitly for it is a mismatch, named.
  options.profile = connex3();
  CHECK(hasDefect(inspectJob(dir / "custom.zip", options), "manifest.json: profile.name: expected \"stratasys-objet500-connex3\""));
}

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
    auto withBomb = files;
    json m = manifestOf(withBomb);
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
    m["files"]["bomb.bin"] = {{"bytes", size}, {"sha256", std::string(hex, 64)}};
    setManifest(withBomb, m);
    auto raw = rawEntries(withBomb);
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
    json m = manifestOf(files);
    m["files"].erase("build.txt");
    setManifest(files, m);
    rezip(dir / "t.zip", files);
    const InspectReport report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "t.zip: build.txt: missing"));
    CHECK(hasDefect(report, "manifest.json: files: lacks build.txt"));
  }
  SECTION("every image of one material removed, with every mention of it in the manifest") {
    auto files = original;
    std::erase_if(files, [](const auto& f) { return f.first.starts_with("TangoBlackPlus_"); });
    json m = manifestOf(files);
    for (auto it = m["files"].begin(); it != m["files"].end();)
      it = it.key().starts_with("TangoBlackPlus_") ? m["files"].erase(it) : std::next(it);
    m["materials"].erase(1);
    for (json& l : m["layers"]) {
      l["files"].erase("TangoBlackPlus");
      l["voxels"].erase("TangoBlackPlus");
    }
    m["orientation_check"].erase("TangoBlackPlus");
    setManifest(files, m);
    rezip(dir / "t.zip", files);
    const InspectReport report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "every TangoBlackPlus image is missing (4 layers)"));
    CHECK(hasDefect(report, "manifest.json: materials: lists 1 materials"));
  }
  SECTION("a layer more in the manifest than in the images") {
    auto files = original;
    json m = manifestOf(files);
    m["layer_count"] = 5;
    setManifest(files, m);
    rezip(dir / "t.zip", files);
    const InspectReport report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "VeroWhitePlus_0004.bmp: missing"));
    CHECK(hasDefect(report, "manifest.json: layers: lists 4 layers; layer_count is 5"));
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

TEST_CASE("The manifest's image size, nesting and value types are checked", "[inspect][hostile]") {
  const fs::path dir = scratch("manifest-values");
  writeSmallJob(dir / "job.zip");
  const auto original = unzip(dir / "job.zip");

  SECTION("images larger than the tray") {
    auto files = original;
    json m = manifestOf(files);
    m["image"]["width"] = 1 << 20;
    setManifest(files, m);
    rezip(dir / "t.zip", files);
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
    CHECK(hasDefect(inspectJob(dir / "t.zip"), "manifest.json: cannot be read: the document holds more than"));
  }
  SECTION("manifest values of the wrong type are described, not serialized") {
    auto files = original;
    json m = manifestOf(files);
    json deep = json::array();
    for (int n = 0; n < 50; ++n) deep = json::array({deep});
    m["frame"]["origin_mm"] = deep;
    m["dithering"]["seed"] = "\x1b[31mred";
    setManifest(files, m);
    rezip(dir / "t.zip", files);
    InspectReport report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "manifest.json: frame.origin_mm: expected an array of three finite numbers, got an array"));
    CHECK(hasDefect(report, "manifest.json: dithering.seed: expected a whole number >= 0, got \"\\x1b[31mred\""));
    m["image"]["format"] = deep;
    setManifest(files, m);
    rezip(dir / "t.zip", files);
    report = inspectJob(dir / "t.zip");
    CHECK(hasDefect(report, "manifest.json: image.format: expected a string, got an array"));
  }
}

// Jobs list XXH3-128 checksums since 2026-12-02 (common/xxh128.hpp) and SHA-256 before: both are read,
// each file's row names exactly one, and a checksum of the wrong length or algorithm is refused.
TEST_CASE("File checksums: XXH3-128, or SHA-256 in older jobs, one per file, each checked", "[inspect][hostile]") {
  const fs::path dir = scratch("checksums");
  writeSmallJob(dir / "job.zip");
  const auto original = unzip(dir / "job.zip");
  const json written = manifestOf(original);
  const std::string layer = written["layers"][1]["files"].begin().value().get<std::string>();
  REQUIRE(xxh128Hex(entryBytes(original, layer)) == written["files"][layer]["xxh128"]);
  const auto inspectWith = [&](const std::function<void(json&)>& edit) {
    auto files = original;
    json m = written;
    edit(m);
    setManifest(files, m);
    rezip(dir / "t.zip", files);
    return inspectJob(dir / "t.zip");
  };
  SECTION("an older job, every file listed by SHA-256, passes; a wrong SHA-256 does not") {
    const auto toSha256 = [&](json& m) {
      for (auto& [name, row] : m["files"].items()) row = {{"bytes", row["bytes"]}, {"sha256", sha256Hex(entryBytes(original, name))}};
    };
    CHECK(inspectWith(toSha256).ok());
    const InspectReport wrong = inspectWith([&](json& m) {
      toSha256(m);
      m["files"][layer]["sha256"] = sha256Hex(std::string_view("another file"));
    });
    CHECK(hasDefect(wrong, layer + ": checksum mismatch"));
  }
  SECTION("a wrong XXH3-128 is a mismatch") {
    const InspectReport report = inspectWith([&](json& m) { m["files"][layer]["xxh128"] = xxh128Hex(std::string_view("x")); });
    CHECK(hasDefect(report, layer + ": checksum mismatch"));
  }
  SECTION("two checksums, none, or one of the wrong form are located") {
    const InspectReport both = inspectWith([&](json& m) { m["files"][layer]["sha256"] = sha256Hex(entryBytes(original, layer)); });
    CHECK(hasDefect(both, "files." + layer + ": holds both \"xxh128\" and \"sha256\"; expected one checksum"));
    const InspectReport none = inspectWith([&](json& m) { m["files"][layer].erase("xxh128"); });
    CHECK(hasDefect(none, "files." + layer + ": has no checksum; expected \"xxh128\""));
    const InspectReport shaLength = inspectWith([&](json& m) { m["files"][layer]["xxh128"] = sha256Hex(entryBytes(original, layer)); });
    CHECK(hasDefect(shaLength, "files." + layer + ".xxh128: expected 32 lowercase hex digits"));
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

// Not a test: writes the seeds of the inspect fuzz target (tests/fuzz/seeds/inspect/), small real jobs
// made by the writer and hostile variants of them, entries stored so that mutations reach their bytes
// (named without .zip, which .gitignore keeps out of the repository).
// Run: RODFAB_SEED_DIR=tests/fuzz/seeds/inspect build/tests/test_inspect "[.make-seeds]"
TEST_CASE("Write the seeds of the inspect fuzz target", "[.make-seeds]") {
  const char* out = std::getenv("RODFAB_SEED_DIR");
  REQUIRE(out);
  const fs::path dir = scratch("seeds"), seeds = out;
  fs::create_directories(seeds);
  // Small inputs keep the kept corpus small: the previews (37 of a small job's 42 KB) become 2 x 2 PNGs,
  // re-listed, and the manifest loses the fields inspect does not read; the jobs stay sound.
  const auto shrink = [](std::vector<std::pair<std::string, Bytes>> files) {
    for (auto& [name, data] : files)
      if (name.starts_with("previews/")) data = encodePngRgb(RgbImage(2, 2, 90, 90, 90));
    json m = manifestOf(files);
    for (const auto& [name, data] : files)
      if (name.starts_with("previews/")) m["files"][name] = {{"bytes", data.size()}, {"xxh128", xxh128Hex(data)}};
    for (const char* key : {"statistics", "metadata", "calibration"}) m.erase(key);
    for (const char* key : {"origin_note", "pixel_to_design_mm", "part_voxels"}) m["frame"].erase(key);
    for (const char* key : {"row_order", "origin", "x_pixels_per_metre", "y_pixels_per_metre"}) m["image"].erase(key);
    for (const char* key : {"printer", "tray_mm", "layer_thickness_mm"}) m["profile"].erase(key);
    m["support"].erase("note");
    for (auto& [name, data] : files)
      if (name == "manifest.json") data = bytesOf(m.dump());
    return files;
  };
  writeSmallJob(dir / "bmp.zip", {.layers = 2});
  writeSmallJob(dir / "bmp-1.zip", {.layers = 1});
  writeSmallJob(dir / "png-explicit.zip", {ArchiveFormat::Zip, ImageFormat::Png, SupportPolicy::Explicit, nullptr, true, 1});
  rezip(seeds / "job-bmp", shrink(unzip(dir / "bmp.zip")), true);
  rezip(seeds / "job-png-explicit", shrink(unzip(dir / "png-explicit.zip")), true);
  CHECK(inspectJob(seeds / "job-bmp").ok());
  CHECK(inspectJob(seeds / "job-png-explicit").ok());
  const auto files = shrink(unzip(dir / "bmp-1.zip"));
  auto raw = rawEntries(files, true);
  raw[1].mode = 0120777;  // build.txt a symbolic link
  raw[2].mode = 0010644;  // a preview a FIFO
  writeRawZip(seeds / "links-and-fifos", raw);
  raw = rawEntries(files, true);
  raw[4].stored = deflateRaw(1u << 20);  // VeroWhitePlus_0000.bmp inflates to 1 MiB, its header unchanged
  raw[4].method = 8;
  raw[4].compressedSize = static_cast<std::uint32_t>(raw[4].stored.size());
  writeRawZip(seeds / "disguised-bomb", raw);
  auto named = files;
  addListed(named, "../x", bytesOf("x"));
  addListed(named, "Build.txt", bytesOf("x"));
  writeRawZip(seeds / "unsafe-names", rawEntries(named, true));
  auto deep = files;
  for (auto& [name, data] : deep)
    if (name == "manifest.json") data = bytesOf(std::string(100, '[') + std::string(100, ']'));
  writeRawZip(seeds / "deep-manifest", rawEntries(deep, true));
  for (const auto& e : fs::directory_iterator(seeds)) CHECK(fs::file_size(e.path()) < 8192);
}
