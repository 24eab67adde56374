// Shared by the inspect tests (tests/test_inspect.cpp, test_inspect_hostile.cpp): small real jobs made
// by the writer, and other code than the reader's to take them apart and damage them: libzip to unpack
// and rebuild archives, a hand-written zip encoder whose headers may lie, zlib for deflate bombs.
#pragma once

#include "common/xxh128.hpp"
#include "printer_profiles/printer_profiles.hpp"
#include "tests/printer_profiles_fixture.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <zip.h>
#include <zlib.h>

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <stdexcept>

namespace rodfab::test {

using namespace printer_profiles;
namespace fs = std::filesystem;
using nlohmann::json;
using common::xxh128Hex;

struct SmallJob {
  ArchiveFormat archive = ArchiveFormat::Zip;
  ImageFormat image = ImageFormat::Bmp;
  SupportPolicy support = SupportPolicy::Printer;
  const Profile* profile = nullptr;  // default: the bundled Connex3
  bool verify = true;                // the writer's own inspection
  int layers = 4;
  std::function<void()> checkInterrupt{};  // JobOptions::checkInterrupt (called by finalize)
};

// A 10 x 6 x `layers`-voxel block of random Vero and Tango, written by the JobWriter.
inline void writeSmallJob(const fs::path& output, const SmallJob& job = {}) {
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
  spec.options.checkInterrupt = job.checkInterrupt;
  if (job.support == SupportPolicy::Explicit) {
    auto tops = std::make_shared<ColumnTops>(planJob(profile, spec.partBounds));
    tops->include(*grid);
    spec.supportTops = tops;
  }
  JobWriter writer(std::move(spec));
  writer.addBand({grid, nullptr, 0, job.layers});
  writer.finalize();
}

inline Bytes bytesOf(const std::string& s) { return Bytes(s.begin(), s.end()); }

// Every entry of a zip, in order, read with libzip directly.
inline std::vector<std::pair<std::string, Bytes>> unzip(const fs::path& file) {
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
inline void rezip(const fs::path& file, const std::vector<std::pair<std::string, Bytes>>& entries, bool store = false) {
  fs::remove(file);
  int error = 0;
  zip_t* za = zip_open(file.c_str(), ZIP_CREATE | ZIP_EXCL, &error);
  REQUIRE(za);
  for (const auto& [name, data] : entries) {
    zip_source_t* source = zip_source_buffer(za, data.data(), data.size(), 0);
    const zip_int64_t index = zip_file_add(za, name.c_str(), source, ZIP_FL_ENC_UTF_8);
    REQUIRE(index >= 0);
    if (store) REQUIRE(zip_set_file_compression(za, static_cast<zip_uint64_t>(index), ZIP_CM_STORE, 0) == 0);
    REQUIRE(zip_file_set_dostime(za, static_cast<zip_uint64_t>(index), kZipEntryTime.time, kZipEntryTime.date, 0) == 0);
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

inline void put16(Bytes& b, std::uint32_t v) { b.insert(b.end(), {std::uint8_t(v), std::uint8_t(v >> 8)}); }
inline void put32(Bytes& b, std::uint32_t v) { b.insert(b.end(), {std::uint8_t(v), std::uint8_t(v >> 8), std::uint8_t(v >> 16), std::uint8_t(v >> 24)}); }

inline void writeRawZip(const fs::path& file, const std::vector<RawEntry>& entries) {
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
inline Bytes deflateRaw(std::uint64_t zeros, const Bytes* data = nullptr) {
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

inline std::uint32_t crcOfZeros(std::uint64_t size) {
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
inline std::vector<RawEntry> rawEntries(const std::vector<std::pair<std::string, Bytes>>& files, bool store = false) {
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

inline const Bytes& entryBytes(const std::vector<std::pair<std::string, Bytes>>& files, const std::string& name) {
  for (const auto& [n, data] : files)
    if (n == name) return data;
  throw std::out_of_range("no entry " + name);
}

inline json manifestOf(const std::vector<std::pair<std::string, Bytes>>& files) {
  for (const auto& [name, data] : files)
    if (name == "manifest.json") return json::parse(data.begin(), data.end());
  FAIL("no manifest");
  return {};
}

inline void setManifest(std::vector<std::pair<std::string, Bytes>>& files, const json& manifest) {
  for (auto& [name, data] : files)
    if (name == "manifest.json") data = bytesOf(manifest.dump());
}

// The job's entries with the manifest changed by `edit(json&)`, every other entry as it was: a job that
// lies about itself, for rezip() and inspect to find.
template <class Edit>
std::vector<std::pair<std::string, Bytes>> tampered(std::vector<std::pair<std::string, Bytes>> files, Edit&& edit) {
  json m = manifestOf(files);
  edit(m);
  setManifest(files, m);
  return files;
}

// Adds `name` to the job and lists it in the manifest with its true size and checksum.
inline void addListed(std::vector<std::pair<std::string, Bytes>>& files, const std::string& name, const Bytes& data) {
  json m = manifestOf(files);
  m["files"][name] = {{"bytes", data.size()}, {"xxh128", xxh128Hex(data)}};
  setManifest(files, m);
  files.emplace_back(name, data);
}

inline bool hasDefect(const InspectReport& report, const std::string& fragment) {
  for (const std::string& d : report.defects)
    if (d.find(fragment) != std::string::npos) return true;
  std::string all;
  for (const std::string& d : report.defects) all += "\n  " + d;
  UNSCOPED_INFO("no defect contains \"" << fragment << "\"; defects:" << all);
  return false;
}

// Peak resident memory of this process so far, in MiB.
inline double peakRssMiB() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

// An entry's bytes as the archive stores them (deflated or not, read with ZIP_FL_COMPRESSED) and what
// its directory records.
struct StoredEntry {
  std::string name;
  Bytes stored;
  bool deflated = false;
  std::uint32_t crc = 0;
};

inline std::vector<StoredEntry> storedEntries(const fs::path& file) {
  int error = 0;
  zip_t* za = zip_open(file.c_str(), ZIP_RDONLY, &error);
  REQUIRE(za);
  std::vector<StoredEntry> out;
  for (zip_int64_t n = 0; n < zip_get_num_entries(za, 0); ++n) {
    zip_stat_t st;
    REQUIRE(zip_stat_index(za, static_cast<zip_uint64_t>(n), 0, &st) == 0);
    Bytes data(st.comp_size);
    zip_file_t* zf = zip_fopen_index(za, static_cast<zip_uint64_t>(n), ZIP_FL_COMPRESSED);
    REQUIRE(zip_fread(zf, data.data(), data.size()) == static_cast<zip_int64_t>(data.size()));
    zip_fclose(zf);
    out.push_back({st.name, std::move(data), st.comp_method == ZIP_CM_DEFLATE, st.crc});
  }
  zip_discard(za);
  return out;
}

// The layer images' stored forms as the writer records them for its verification (InspectOptions::
// storedForms), taken here from the archive itself.
inline void useStoredForms(InspectOptions& options, const fs::path& file) {
  options.storedForms.clear();
  for (const StoredEntry& e : storedEntries(file))
    if (e.name.find('/') == std::string::npos && (e.name.ends_with(".bmp") || e.name.ends_with(".png")))
      options.storedForms[e.name] = {xxh128Hex(e.stored), e.stored.size(), e.crc, e.deflated};
}

// Flips one bit in the middle of an entry's stored bytes, in place: its headers and directory record
// stay as they were.
inline void flipStoredBit(const fs::path& file, const std::string& name) {
  std::size_t storedBytes = 0;
  for (const StoredEntry& e : storedEntries(file))
    if (e.name == name) storedBytes = e.stored.size();
  REQUIRE(storedBytes > 0);
  Bytes zip = readAll(file);
  for (std::size_t at = 0; at + 30 + name.size() < zip.size(); ++at) {
    const auto u16 = [&](std::size_t p) { return static_cast<std::size_t>(zip[p] | zip[p + 1] << 8); };
    if (zip[at] != 'P' || zip[at + 1] != 'K' || zip[at + 2] != 3 || zip[at + 3] != 4 || u16(at + 26) != name.size() ||
        !std::equal(name.begin(), name.end(), zip.begin() + static_cast<std::ptrdiff_t>(at + 30)))
      continue;
    zip[at + 30 + name.size() + u16(at + 28) + storedBytes / 2] ^= 0x10;
    writeAll(file, zip);
    return;
  }
  FAIL("no local header for " << name);
}

// Kills the test program if an inspection hangs (a FIFO opened for reading, /dev/stdin read).
struct HangGuard {
  explicit HangGuard(unsigned seconds) { ::alarm(seconds); }
  ~HangGuard() { ::alarm(0); }
};

}  // namespace rodfab::test
