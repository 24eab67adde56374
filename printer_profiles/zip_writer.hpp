// Writing a job's zip archive (libzip): entries in a fixed order with fixed timestamps and attributes,
// from files, from memory, or copied as staged in their compressed form.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

// When a file's contents go into the zip deflated (fast level) or as they are.
enum class ZipStorage { Deflate, Store };

// An entry's data already in its zip form: raw deflate (RFC 1951) for ZipStorage::Deflate, the contents
// themselves for Store. libzip copies it as it is. The bytes are either in memory (`inMemory`: `memory`,
// which whoever staged them keeps alive until writeZip returns) or at [offset, offset + length) of the
// staged file writeZip is given.
struct StagedZipData {
  std::uint64_t offset = 0, length = 0;  // in the staged file; `offset` is unused when `inMemory`
  std::uint64_t size = 0;    // of the contents, uncompressed
  std::uint32_t crc32 = 0;   // of the contents (zipCrc32, deflate.hpp)
  std::string xxh128{};      // of the staged bytes, for the writer's verification (InspectOptions::storedForms)
  bool inMemory = false;     // said, not inferred from `memory`: an empty entry may be kept in memory too
  std::span<const std::uint8_t> memory{};  // the bytes when `inMemory` (`length` of them)
  ZipStorage storage = ZipStorage::Deflate;  // what the bytes are: deflated, or the contents as they are
};

struct ZipEntry {
  std::string name;                  // inside the archive
  std::filesystem::path source;      // file on disk, read by libzip when the archive is closed
  ZipStorage storage = ZipStorage::Deflate;  // how the entry is stored (for `staged`, what its bytes are)
  // Instead of `source`: data compressed beforehand (in parallel, band by band), copied into the
  // archive without recompressing; its own `storage` must be the entry's (writeZip: std::logic_error).
  std::optional<StagedZipData> staged;
};

struct ZipMemoryEntry {
  std::string name;
  std::span<const std::uint8_t> data;  // must stay alive until writeZipFromMemory returns
  ZipStorage storage = ZipStorage::Deflate;
};

// Every entry's DOS timestamp: noon, 1 January 2020. Zip stores a local time without its zone, so the
// fields are set as they are (zip_file_set_dostime): converted from a time_t, they followed the
// machine's time zone (TZ=JST-9 gave 21:00), and the same job had other bytes elsewhere.
struct ZipDosTime {
  std::uint16_t time, date;
};
inline constexpr ZipDosTime kZipEntryTime{12 << 11, ((2020 - 1980) << 9) | (1 << 5) | 1};

// Writes a new zip holding `entries` in the given order; the bytes depend on nothing but the
// entries' contents, names and storage, and for staged entries their compressed bytes (fixed
// timestamps and attributes). Staged entries not in memory are read from `stagedFile` (one file, held
// once here rather than by every entry; opened when the first of them is read, never when none is).
// Throws std::runtime_error naming the archive when it cannot be written (the file cannot be created,
// an entry's data cannot be read or is shorter than recorded; for a staged entry the message names the
// entry and the staged file, and where in it); nothing is left at `zipPath` then.
void writeZip(const std::filesystem::path& zipPath, const std::vector<ZipEntry>& entries, const std::filesystem::path& stagedFile);
// The same from memory (deflated by libzip with zlib).
void writeZipFromMemory(const std::filesystem::path& zipPath, const std::vector<ZipMemoryEntry>& entries);

}  // namespace rodfab::printer_profiles
