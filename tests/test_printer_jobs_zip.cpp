// printer_profiles/ zip files: the archive writer's own output file (zip_output.hpp) against libzip's
// file output, byte for byte, and the read-ahead reader (zip_input.hpp) against the contents written.
#include "printer_profiles/job_reader.hpp"  // internal: the hostile-input reader `inspect` uses
#include "printer_profiles/zip_writer.hpp"

#include <catch2/catch.hpp>
#include <zip.h>

#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace rodfab::printer_profiles;

namespace {

fs::path scratchDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("rodfab-test-zip-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Entries of every size class the writer meets: many small ones (layer images of a sparse part), and
// ones larger than the output's 8 MiB buffer and the reader's 1 MiB read-ahead, so local headers are
// rewritten both inside and outside the buffered tail. Half compressible, half random.
std::vector<Bytes> contents() {
  std::mt19937 rng(7);
  std::vector<Bytes> all;
  const std::size_t sizes[] = {0, 1, 30, 4096, 8191, 8192, 8193, 70'000, (1u << 20) + 3, (9u << 20) + 17};
  for (int n = 0; n < 200; ++n) {
    Bytes data(sizes[n % 10] / (n % 7 == 0 ? 1 : 16));
    for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<std::uint8_t>(n % 2 ? rng() : (i / 97) % 5);
    all.push_back(std::move(data));
  }
  return all;
}

std::vector<ZipMemoryEntry> entriesOf(const std::vector<Bytes>& all) {
  std::vector<ZipMemoryEntry> entries;
  for (std::size_t n = 0; n < all.size(); ++n) {
    std::string name = "d";
    name += static_cast<char>('0' + n % 3);
    name.append("/f").append(std::to_string(n)).append(".bin");
    entries.push_back({name, all[n], n % 3 == 0 ? ZipStorage::Store : ZipStorage::Deflate});
  }
  return entries;
}

// The same archive written by libzip through its own file output, with the writer's fixed settings.
void writeWithLibzipFile(const fs::path& path, const std::vector<ZipMemoryEntry>& entries) {
  int error = 0;
  zip_t* za = zip_open(path.c_str(), ZIP_CREATE | ZIP_EXCL, &error);
  REQUIRE(za);
  for (const ZipMemoryEntry& e : entries) {
    const zip_int64_t i = zip_file_add(za, e.name.c_str(), zip_source_buffer(za, e.data.data(), e.data.size(), 0), ZIP_FL_ENC_UTF_8);
    REQUIRE(i >= 0);
    const auto index = static_cast<zip_uint64_t>(i);
    const bool deflate = e.storage == ZipStorage::Deflate;
    REQUIRE(zip_set_file_compression(za, index, deflate ? ZIP_CM_DEFLATE : ZIP_CM_STORE, deflate ? 1 : 0) == 0);
    REQUIRE(zip_file_set_mtime(za, index, static_cast<time_t>(kZipEntryTime), 0) == 0);
    REQUIRE(zip_file_set_external_attributes(za, index, 0, ZIP_OPSYS_UNIX, 0100644u << 16) == 0);
  }
  REQUIRE(zip_close(za) == 0);
}

Bytes fileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace

TEST_CASE("The archive writer's output file holds the bytes libzip's own file output writes", "[job][zip]") {
  const fs::path dir = scratchDir("output");
  const std::vector<Bytes> all = contents();
  const std::vector<ZipMemoryEntry> entries = entriesOf(all);
  writeZipFromMemory(dir / "ours.zip", entries);
  writeWithLibzipFile(dir / "libzip.zip", entries);
  const Bytes ours = fileBytes(dir / "ours.zip");
  CHECK(ours.size() > (10u << 20));
  CHECK((ours == fileBytes(dir / "libzip.zip")));
  CHECK_FALSE(fs::exists(dir / "ours.zip.part"));
  CHECK((fs::status(dir / "ours.zip").permissions() == fs::status(dir / "libzip.zip").permissions()));
  fs::remove_all(dir);
}

TEST_CASE("The archive writer never replaces a file, and a failed write leaves nothing behind", "[job][zip]") {
  const fs::path dir = scratchDir("refuse");
  const Bytes data{'a', 'b', 'c'};
  {
    std::ofstream(dir / "taken.zip") << "a user's file";
  }
  CHECK_THROWS_AS(writeZipFromMemory(dir / "taken.zip", {{"a.txt", data, ZipStorage::Deflate}}), std::runtime_error);
  CHECK(fs::file_size(dir / "taken.zip") == std::string("a user's file").size());
  fs::create_symlink(dir / "nowhere", dir / "link.zip");  // a dangling link is not followed either
  CHECK_THROWS_AS(writeZipFromMemory(dir / "link.zip", {{"a.txt", data, ZipStorage::Deflate}}), std::runtime_error);
  CHECK_FALSE(fs::exists(dir / "nowhere"));

  // A staged entry whose file is shorter than recorded fails the write half-way.
  {
    std::ofstream(dir / "staged.bin", std::ios::binary) << "0123456789";
  }
  const std::vector<ZipEntry> entries{{"ok.bin", {}, ZipStorage::Store, StagedZipData{0, 5, 5, 0}},
                                      {"short.bin", {}, ZipStorage::Store, StagedZipData{5, 50, 50, 0}}};
  CHECK_THROWS_AS(writeZip(dir / "short.zip", entries, dir / "staged.bin"), std::runtime_error);
  CHECK_FALSE(fs::exists(dir / "short.zip"));
  CHECK_FALSE(fs::exists(dir / "short.zip.part"));
  fs::remove_all(dir);
}

TEST_CASE("The job reader reads every entry back as written, stored and raw, across its read-ahead", "[job][zip]") {
  const fs::path dir = scratchDir("input");
  const std::vector<Bytes> all = contents();
  const std::vector<ZipMemoryEntry> entries = entriesOf(all);
  writeZipFromMemory(dir / "job.zip", entries);
  const std::unique_ptr<JobReader> reader = openJobReader(dir / "job.zip", 10'000, 4);
  REQUIRE(reader->entries().size() == all.size());
  for (std::size_t n = 0; n < all.size(); ++n) {
    const JobEntry& entry = reader->entries()[n];
    REQUIRE(entry.name == entries[n].name);
    CHECK((reader->read(entry, all[n].size()) == all[n]));
    if (entries[n].storage == ZipStorage::Store) {
      Bytes raw;
      const StoredEntryInfo info = reader->streamStored(entry, all[n].size(), [&](std::span<const std::uint8_t> piece) {
        raw.insert(raw.end(), piece.begin(), piece.end());
      });
      CHECK_FALSE(info.deflated);
      CHECK((raw == all[n]));
    }
  }
  // Cut short: the reader reports the damage instead of reading past the end.
  fs::resize_file(dir / "job.zip", fs::file_size(dir / "job.zip") / 2);
  bool refused = false;
  try {
    const std::unique_ptr<JobReader> cut = openJobReader(dir / "job.zip", 10'000, 4);
    for (const JobEntry& entry : cut->entries()) (void)cut->read(entry, 64u << 20);
  } catch (const JobReadError&) {
    refused = true;
  }
  CHECK(refused);
  fs::remove_all(dir);
}
