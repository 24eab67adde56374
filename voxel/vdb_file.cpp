#include "voxel/vdb_file.hpp"

#include "common/file_hasher.hpp"
#include "common/interrupt.hpp"
#include "common/output_file.hpp"

#include <openvdb/io/Archive.h>
#include <openvdb/io/File.h>

#include <unistd.h>

#include <array>
#include <algorithm>
#include <cstdint>
#include <span>
#include <string>
#include <vector>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <stdexcept>
#include <system_error>

namespace rodfab::voxel {

namespace {

constexpr const char* kWriterKey = "rodfab_writer";

void initializeOpenVdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

// A file buffer that stops the writing it serves on SIGINT or SIGTERM: OpenVDB compresses and
// writes node by node without looking, and a large grid took over a second of CPU after the signal
// (the watchdog then cut it short). Interrupted thrown here comes out of the stream's write
// (badbit is in its exceptions) and through OpenVDB.
class InterruptibleFileBuffer final : public std::filebuf {
protected:
  std::streamsize xsputn(const char* bytes, std::streamsize count) override {
    common::throwIfInterrupted();
    return std::filebuf::xsputn(bytes, count);
  }
  int_type overflow(int_type c) override {
    common::throwIfInterrupted();
    return std::filebuf::overflow(c);
  }
};

// What io::File::write does (Archive::write on a seekable stream), on a stream of ours that is checked
// once written: io::File never looks at its stream, so a full disk left a truncated file that was then
// put in place with exit 0.
class GridArchive final : public openvdb::io::Archive {
public:
  void writeFile(const std::filesystem::path& file, const openvdb::GridCPtrVec& grids, const openvdb::MetaMap& metadata) const {
    InterruptibleFileBuffer buffer;
    if (!buffer.open(file, std::ios::out | std::ios::binary | std::ios::trunc)) throw std::runtime_error("cannot create " + file.string());
    std::ostream out(&buffer);
    out.exceptions(std::ios::badbit);
    try {
      write(out, grids, /*seekable=*/true, metadata);
      out.exceptions(std::ios::goodbit);
    } catch (const std::ios_base::failure&) {  // a write failed: badbit
      out.exceptions(std::ios::goodbit);
    }
    if (!buffer.close()) out.setstate(std::ios::failbit);
    if (!out) throw std::runtime_error("writing " + file.string() + " failed (disk full?)");
  }
};

// OpenVDB's header (Archive::writeHeader): magic (8 bytes), file version (4), library version (4 + 4),
// a grid-offsets flag (1), then the archive's UUID as 36 characters, random for every file written.
constexpr std::size_t kUuidAt = 21;
constexpr std::size_t kUuidLength = 36;

bool looksLikeUuid(const std::array<char, kUuidLength>& text) {
  for (std::size_t n = 0; n < kUuidLength; ++n) {
    const bool dash = n == 8 || n == 13 || n == 18 || n == 23;
    const char c = text[n];
    if (dash ? c != '-' : !((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f') || (c >= 'A' && c <= 'F'))) return false;
  }
  return true;
}

// Replaces the random UUID with one made from the file's other bytes (their XXH3-128, as an RFC 9562
// version 8 UUID): the same grid and metadata give the same file, whatever the run or thread count,
// and different files still get different UUIDs (what OpenVDB compares them by).
void giveContentUuid(const std::filesystem::path& file) {
  std::fstream io(file, std::ios::binary | std::ios::in | std::ios::out);
  if (!io.is_open()) throw std::runtime_error("cannot reopen " + file.string() + " to give it its UUID");
  std::array<char, kUuidAt + kUuidLength> header{};
  io.read(header.data(), static_cast<std::streamsize>(header.size()));
  std::array<char, kUuidLength> written{};
  std::copy(header.begin() + kUuidAt, header.end(), written.begin());
  if (!io || !looksLikeUuid(written)) throw std::logic_error(file.string() + ": OpenVDB's header has no UUID where expected");
  common::FileHasher hasher(common::HashAlgorithm::Xxh128);
  const auto bytes = [](const std::vector<char>& v, std::size_t n) { return std::span(reinterpret_cast<const std::uint8_t*>(v.data()), n); };
  std::vector<char> chunk(header.begin(), header.begin() + kUuidAt);
  hasher.update(bytes(chunk, chunk.size()));  // the UUID's own bytes left out
  chunk.resize(std::size_t{1} << 20);
  while (io.read(chunk.data(), static_cast<std::streamsize>(chunk.size())) || io.gcount() > 0)
    hasher.update(bytes(chunk, static_cast<std::size_t>(io.gcount())));
  std::string hex = hasher.hex();
  hex[12] = '8';                                                    // version 8: made by the writer
  hex[16] = "89ab"[std::stoi(hex.substr(16, 1), nullptr, 16) & 3];  // variant 10
  const std::string uuid = hex.substr(0, 8) + '-' + hex.substr(8, 4) + '-' + hex.substr(12, 4) + '-' + hex.substr(16, 4) + '-' + hex.substr(20);
  io.clear();  // the read ended at the end of the file
  io.seekp(static_cast<std::streamoff>(kUuidAt));
  io.write(uuid.data(), static_cast<std::streamsize>(uuid.size()));
  io.close();
  if (!io) throw std::runtime_error("writing " + file.string() + " failed (disk full?)");
}

}  // namespace

void writeGridFile(const std::string& path, const openvdb::GridBase& grid, const openvdb::MetaMap& fileMetadata) {
  initializeOpenVdb();
  common::AtomicOutput output(path);
  try {
    openvdb::MetaMap metadata(fileMetadata);
    metadata.insertMeta(kWriterKey, openvdb::StringMetadata("rodfab"));
    GridArchive().writeFile(output.temporary(), {grid.copyGrid()}, metadata);
    giveContentUuid(output.temporary());
  } catch (const common::Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": cannot write the grid: " + e.what());
  }
  output.commit();
}

bool isGridFile(const std::string& path) {
  // OpenVDB files start with the magic number 0x56444220 (little-endian " BDV"); the file metadata,
  // with our writer key, follows within the first few hundred bytes.
  return common::fileStartsWith(path, std::string_view(" BDV", 4), kWriterKey, 4096);
}

openvdb::FloatGrid::Ptr readFloatGrid(const std::string& path, const std::string& gridName) {
  initializeOpenVdb();
  openvdb::GridBase::Ptr base;
  try {
    openvdb::io::File file(path);
    file.open();
    if (!file.hasGrid(gridName)) throw std::runtime_error("no grid named '" + gridName + "'");
    base = file.readGrid(gridName);
    file.close();
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": cannot read grid '" + gridName + "': " + e.what());
  }
  auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(base);
  if (!grid) throw std::runtime_error(path + ": grid '" + gridName + "' holds " + base->valueType() + ", expected float");
  return grid;
}

}  // namespace rodfab::voxel
