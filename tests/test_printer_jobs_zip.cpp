// printer_profiles/ zip files: the archive writer's own output file (zip_output.hpp) against libzip's
// file output, byte for byte, the read-ahead reader (zip_input.hpp) against the contents written, the
// libzip source adapter (zip_source_adapter.hpp) and staged entries in memory or in the staged file.
#include "printer_profiles/deflate.hpp"
#include "printer_profiles/job_reader.hpp"  // internal: the hostile-input reader `inspect` uses
#include "printer_profiles/zip_source_adapter.hpp"  // internal: the libzip callback every source of ours goes through
#include "printer_profiles/zip_writer.hpp"
#include "tests/printer_jobs_fixture.hpp"

#include <catch2/catch.hpp>
#include <zip.h>

#include <unistd.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <new>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
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
// ones larger than the output's 512 KiB buffer and the reader's 1 MiB read-ahead, so local headers are
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
    REQUIRE(zip_file_set_dostime(za, index, kZipEntryTime.time, kZipEntryTime.date, 0) == 0);
    REQUIRE(zip_file_set_external_attributes(za, index, 0, ZIP_OPSYS_UNIX, 0100644u << 16) == 0);
  }
  REQUIRE(zip_close(za) == 0);
}

Bytes fileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// An empty source through the adapter, whose read throws when told to; counts its deletions.
class ProbeSource : public ZipSourceState {
public:
  static constexpr std::array kCommands{ZIP_SOURCE_OPEN, ZIP_SOURCE_READ, ZIP_SOURCE_CLOSE, ZIP_SOURCE_STAT};
  enum class Read { Empty, BadAlloc, Throws };
  ProbeSource(Read how, int& deleted) : how_(how), deleted_(deleted) {}
  ~ProbeSource() { ++deleted_; }
  zip_int64_t open() { return 0; }
  zip_int64_t read(void*, zip_uint64_t) {
    if (how_ == Read::BadAlloc) throw std::bad_alloc();
    if (how_ == Read::Throws) throw std::runtime_error("not for libzip's C frames");
    return 0;
  }
  zip_int64_t close() { return 0; }
  zip_int64_t stat(zip_stat_t* st) {
    zip_stat_init(st);
    st->size = 0;
    st->valid = ZIP_STAT_SIZE;
    return 0;
  }

private:
  Read how_;
  int& deleted_;
};

// Sources the adapter's check refuses: an operation misspelt (it lists STAT, has `stats`), and an
// operation libzip would never be told of (it has `tell` and does not list it).
struct MisspeltSource : ZipSourceState {
  static constexpr std::array kCommands{ZIP_SOURCE_OPEN, ZIP_SOURCE_STAT};
  zip_int64_t open() { return 0; }
  zip_int64_t stats(zip_stat_t*) { return 0; }
};
struct UnlistedSource : ZipSourceState {
  static constexpr std::array kCommands{ZIP_SOURCE_OPEN};
  zip_int64_t open() { return 0; }
  zip_int64_t tell() { return 0; }
};
static_assert(zip_source_detail::listsExactlyItsOperations<ProbeSource>());
static_assert(!zip_source_detail::listsExactlyItsOperations<MisspeltSource>());
static_assert(!zip_source_detail::listsExactlyItsOperations<UnlistedSource>());

// The libzip error code a source reports through ZIP_SOURCE_ERROR (zip_error_to_data's two ints).
int reportedError(ProbeSource& source) {
  int codes[2] = {};
  REQUIRE(zip_source_detail::callback<ProbeSource>(&source, codes, sizeof codes, ZIP_SOURCE_ERROR) == sizeof codes);
  return codes[0];
}

}  // namespace

TEST_CASE("The libzip source adapter answers ERROR, FREE and SUPPORTS itself and throws nothing into libzip", "[job][zip]") {
  int deleted = 0;
  // Told exactly libzip's readable set: the source's four operations, ERROR and FREE.
  CHECK(zip_source_detail::callback<ProbeSource>(nullptr, nullptr, 0, ZIP_SOURCE_SUPPORTS) == ZIP_SOURCE_SUPPORTS_READABLE);
  auto* source = new ProbeSource(ProbeSource::Read::Empty, deleted);
  CHECK(zip_source_detail::callback<ProbeSource>(source, nullptr, 0, ZIP_SOURCE_TELL) == -1);  // no operation
  CHECK(reportedError(*source) == ZIP_ER_OPNOTSUPP);
  CHECK(zip_source_detail::callback<ProbeSource>(source, nullptr, 0, ZIP_SOURCE_OPEN) == 0);
  CHECK(zip_source_detail::callback<ProbeSource>(source, nullptr, 0, ZIP_SOURCE_FREE) == 0);
  CHECK(deleted == 1);

  // Through libzip: what an operation throws becomes a libzip error, and libzip's free deletes the source.
  for (const auto& [how, code] : {std::pair{ProbeSource::Read::BadAlloc, ZIP_ER_MEMORY}, std::pair{ProbeSource::Read::Throws, ZIP_ER_INTERNAL}}) {
    zip_error_t error;
    zip_error_init(&error);
    zip_source_t* made = makeZipSource(std::make_unique<ProbeSource>(how, deleted), &error);
    REQUIRE(made);
    REQUIRE(zip_source_open(made) == 0);
    char byte = 0;
    CHECK(zip_source_read(made, &byte, 1) == -1);
    CHECK(zip_error_code_zip(zip_source_error(made)) == code);
    zip_source_close(made);
    zip_source_free(made);
    zip_error_fini(&error);
  }
  CHECK(deleted == 3);
}

TEST_CASE("Staged entries kept in memory are read from memory, even empty ones, the staged file only for the others", "[job][zip]") {
  const fs::path dir = scratchDir("staged-memory");
  const Bytes kept{'k', 'e', 'p', 't'}, none;
  {
    std::ofstream(dir / "staged.bin", std::ios::binary) << "filed";
  }
  const auto inMemory = [](const Bytes& data) {
    StagedZipData z{0, data.size(), data.size(), zipCrc32(data)};
    z.storage = ZipStorage::Store;
    z.inMemory = true;
    z.memory = data;
    return z;
  };
  std::vector<ZipEntry> entries{{"empty.bin", {}, ZipStorage::Store, inMemory(none)},
                                {"kept.bin", {}, ZipStorage::Store, inMemory(kept)}};
  // Only in-memory entries: the staged file is never opened (here it does not exist). Before the flag, an
  // empty entry counted as "in the staged file" and failed to open it.
  writeZip(dir / "memory.zip", entries, dir / "absent.bin");
  const Bytes filed{'f', 'i', 'l', 'e', 'd'};
  entries.push_back({"filed.bin", {}, ZipStorage::Store, StagedZipData{.offset = 0, .length = 5, .size = 5, .crc32 = zipCrc32(filed), .storage = ZipStorage::Store}});
  writeZip(dir / "both.zip", entries, dir / "staged.bin");
  const std::unique_ptr<JobReader> reader = openJobReader(dir / "both.zip", 10, 4);
  REQUIRE(reader->entries().size() == 3);
  CHECK(reader->read(reader->entries()[0], 10).empty());
  CHECK((reader->read(reader->entries()[1], 10) == kept));
  CHECK((reader->read(reader->entries()[2], 10) == filed));
  CHECK(openJobReader(dir / "memory.zip", 10, 4)->entries().size() == 2);

  // An entry in the staged file when that file cannot be opened, and an in-memory entry whose bytes are
  // not as long as recorded: the archive is not written.
  // The error names the entry and the staged file (libzip's own names neither).
  using Catch::Matchers::Contains;
  CHECK_THROWS_WITH(writeZip(dir / "absent.zip", entries, dir / "absent.bin"),
                    Contains("absent.zip: cannot write the archive: filed.bin: cannot open " + (dir / "absent.bin").string() +
                             " (No such file or directory)"));
  CHECK_FALSE(fs::exists(dir / "absent.zip"));
  // A staged file that opens but cannot be read (a folder: EISDIR, as a failing disk gives EIO).
  fs::create_directory(dir / "folder.bin");
  CHECK_THROWS_WITH(writeZip(dir / "unreadable.zip", entries, dir / "folder.bin"),
                    Contains("filed.bin: cannot read " + (dir / "folder.bin").string() + " at bytes 0 to 5 (Is a directory)") &&
                        !Contains("Read error"));  // the reason once, not libzip's repetition of it
  CHECK_FALSE(fs::exists(dir / "unreadable.zip"));
  entries[1].staged->length = 3;
  CHECK_THROWS_WITH(writeZip(dir / "inconsistent.zip", {entries[1]}, dir / "staged.bin"),
                    Contains("kept.bin: its 4 bytes kept in memory, recorded as 3"));
  CHECK_FALSE(fs::exists(dir / "inconsistent.zip"));
  fs::remove_all(dir);
}

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
  const std::vector<ZipEntry> entries{{"ok.bin", {}, ZipStorage::Store, StagedZipData{.offset = 0, .length = 5, .size = 5, .storage = ZipStorage::Store}},
                                      {"short.bin", {}, ZipStorage::Store, StagedZipData{.offset = 5, .length = 50, .size = 50, .storage = ZipStorage::Store}}};
  CHECK_THROWS_WITH(writeZip(dir / "short.zip", entries, dir / "staged.bin"),
                    Catch::Matchers::Contains("short.bin: " + (dir / "staged.bin").string() + " at bytes 5 to 55: the file ends first"));
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
  // From the last entry to the first: every read starts away from where the last one ended (a page,
  // then read-aheads doubling as the entry goes on).
  const std::unique_ptr<JobReader> backwards = openJobReader(dir / "job.zip", 10'000, 4);
  for (std::size_t n = all.size(); n-- > 0;) CHECK((backwards->read(backwards->entries()[n], all[n].size()) == all[n]));
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

namespace {

// Layer 0 fills a 1024 x 520 image (66 KB) with white noise, which deflate would not shrink; layer 1
// holds two 16 x 16 patches at its corners, an image of the same size but nearly blank.
openvdb::BoolGrid::Ptr noiseGrid() {
  const auto grid = rodfab::test::newGrid();
  auto acc = grid->getAccessor();
  std::mt19937 random(11);
  std::bernoulli_distribution vero(0.5);
  for (int j = 0; j < 520; ++j)
    for (int i = 0; i < 1024; ++i) {
      acc.setValueOn({i, j, 0}, vero(random));
      if ((i < 16 && j < 16) || (i >= 1008 && j >= 504)) acc.setValueOn({i, j, 1}, vero(random));
    }
  return grid;
}

// Every pixel of a decoded layer image against the grid: set where the voxel is on and of the image's
// material (rigid or not), through the job's frame (column 0 at i0, row 0 at j0).
void sameAsGrid(const openvdb::BoolGrid& grid, const DecodedBitmap& d, int layer, bool rigid, int i0, int j0) {
  const auto acc = grid.getConstAccessor();
  REQUIRE(d.bitmap.width() >= 1024);
  REQUIRE(d.bitmap.height() >= 520);
  std::size_t wrong = 0, set = 0;
  for (int r = 0; r < d.bitmap.height(); ++r)
    for (int c = 0; c < d.bitmap.width(); ++c) {
      bool value = false;
      const bool on = acc.probeValue({i0 + c, j0 - r, layer}, value);
      wrong += d.bitmap.get(c, r) != (on && value == rigid) ? 1 : 0;
      set += d.bitmap.get(c, r) ? 1 : 0;
    }
  CHECK(wrong == 0);
  CHECK(set > (layer == 0 ? 200'000u : 100u));
}

}  // namespace

TEST_CASE("Layer images of dithered noise are stored, mostly blank ones deflated, the job decodes back and inspects clean", "[job][zip]") {
  const auto grid = noiseGrid();
  const fs::path dir = scratchDir("noise");
  rodfab::test::writeJob(*grid, rodfab::test::specFor(*grid, dir / "noise.zip"), 1);
  CHECK(inspectJob(dir / "noise.zip").ok());

  // libzip's view of the layer images: method, and contents against the grid through decodeBmp.
  int error = 0;
  zip_t* za = zip_open((dir / "noise.zip").c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &error);
  REQUIRE(za);
  const auto entry = [za](zip_uint64_t n, std::uint64_t size) {
    Bytes file(size);
    zip_file_t* zf = zip_fopen_index(za, n, 0);
    REQUIRE(zf);
    CHECK(zip_fread(zf, file.data(), file.size()) == static_cast<zip_int64_t>(file.size()));  // libzip checks the CRC
    zip_fclose(zf);
    return file;
  };
  zip_stat_t manifestStat;
  REQUIRE(zip_stat(za, "manifest.json", 0, &manifestStat) == 0);
  const Bytes text = entry(manifestStat.index, manifestStat.size);
  const nlohmann::json frame = nlohmann::json::parse(text.begin(), text.end())["frame"];
  const int i0 = frame["first_column_i"], j0 = frame["top_row_j"];
  int images = 0;
  for (zip_int64_t n = 0; n < zip_get_num_entries(za, 0); ++n) {
    zip_stat_t st;
    REQUIRE(zip_stat_index(za, static_cast<zip_uint64_t>(n), 0, &st) == 0);
    const std::string name = st.name;
    const bool rigid = name.starts_with("VeroWhitePlus_"), rubbery = name.starts_with("TangoBlackPlus_");
    if (!rigid && !rubbery) continue;
    CAPTURE(name);
    const int layer = name.ends_with("0000.bmp") ? 0 : 1;
    CHECK(st.comp_method == (layer == 0 ? ZIP_CM_STORE : ZIP_CM_DEFLATE));
    sameAsGrid(*grid, decodeBmp(entry(static_cast<zip_uint64_t>(n), st.size)), layer, rigid, i0, j0);
    ++images;
  }
  zip_discard(za);
  CHECK(images == 4);

  // PNG layers: the noise in stored deflate blocks inside IDAT, read by libpng.
  JobSpec png = rodfab::test::specFor(*grid, dir / "noise-png");
  png.options.archive = ArchiveFormat::Directory;
  png.options.imageFormat = ImageFormat::Png;
  rodfab::test::writeJob(*grid, png, 2);
  CHECK(inspectJob(dir / "noise-png").ok());
  const Bytes layer0 = rodfab::test::readAll(dir / "noise-png" / "VeroWhitePlus_0000.png");
  CHECK(layer0.size() > 66'000);  // 1 bit a pixel as it is
  // The IDAT's zlib stream (after the 8-byte signature, IHDR's 25 bytes, pHYs's 21, IDAT's length and
  // type) opens with a stored block: BTYPE 00 in bits 1-2 of the first byte after the 2-byte header.
  const std::size_t idat = 8 + 25 + 21;
  REQUIRE(std::string(layer0.begin() + idat + 4, layer0.begin() + idat + 8) == "IDAT");
  CHECK(((layer0[idat + 8 + 2] >> 1) & 3) == 0);
  const Bytes blank = rodfab::test::readAll(dir / "noise-png" / "VeroWhitePlus_0001.png");  // nearly blank: deflated
  CHECK(((blank[idat + 8 + 2] >> 1) & 3) != 0);
  sameAsGrid(*grid, decodePng1(layer0), 0, true, i0, j0);
  sameAsGrid(*grid, decodePng1(rodfab::test::readAll(dir / "noise-png" / "TangoBlackPlus_0001.png")), 1, false, i0, j0);
  fs::remove_all(dir);
}
