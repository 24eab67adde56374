// A job on disk, as a zip archive (libzip) or a plain directory: reading its files, writing the zip
// in a fixed entry order with fixed timestamps.
#pragma once

#include "printer_profiles/bitmap.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

inline constexpr const char* kJobFormat = "rodfab.job/1";
inline constexpr const char* kManifestName = "manifest.json";
// The job report (slicer/job_report.hpp), named by the manifest's "report" when the job has one.
inline constexpr const char* kReportName = "report.html";
// The largest manifest.json read when telling whether an existing path is a rodfab job: a job of the
// profile maxima (65,536 layers, three bitmaps each) writes under 64 MB.
inline constexpr std::size_t kMaxManifestBytes = std::size_t{128} << 20;

enum class ArchiveFormat { Zip, Directory };
const char* toString(ArchiveFormat format);

// Raised when a job cannot be opened or one of its files cannot be read; names the job and file.
class JobReadError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

// Read access to the files of a job, by their names inside the job ('/' separated).
class JobFiles {
public:
  virtual ~JobFiles() = default;
  virtual const std::filesystem::path& path() const = 0;
  virtual ArchiveFormat format() const = 0;
  // Every file, sorted by name.
  virtual std::vector<std::string> names() const = 0;
  virtual bool contains(const std::string& name) const = 0;
  // Safe to call from several threads at once.
  virtual Bytes read(const std::string& name) const = 0;
};

// A directory is read as a directory job, anything else as a zip archive.
std::unique_ptr<JobFiles> openJobFiles(const std::filesystem::path& job);

// What lies at a job's output path, found without following a symbolic link, without waiting on a
// pipe or device, and reading at most kMaxManifestBytes plus a zip's directory.
struct OutputOccupant {
  enum class Kind {
    Nothing,    // no entry of that name
    RodfabJob,  // a zip whose first entry is a manifest.json of format kJobFormat, or a folder holding
                // such a manifest and nothing but regular files its "files" table lists (previews/ too)
    Other,      // anything else: a user's file or folder, a link, a foreign zip, a job with added files
  };
  Kind kind = Kind::Nothing;
  std::string description;              // what it is, for messages: "a folder holding notes.txt, which ..."
  std::uint64_t device = 0, inode = 0;  // of the entry itself (not a link's target)
};
// Never throws for what it finds (an unreadable entry is Other, described with the error).
OutputOccupant examineOutput(const std::filesystem::path& path);

// When a file's contents go into the zip deflated (fast level) or as they are.
enum class ZipStorage { Deflate, Store };

// An entry's data already in its zip form, at [offset, offset + length) of a staged file: raw deflate
// (RFC 1951) for ZipStorage::Deflate, the contents themselves for Store. libzip copies it as it is.
struct StagedZipData {
  std::filesystem::path file;
  std::uint64_t offset = 0, length = 0;
  std::uint64_t size = 0;    // of the contents, uncompressed
  std::uint32_t crc32 = 0;   // of the contents (zipCrc32, deflate.hpp)
  std::string xxh128{};      // of the staged bytes, for the writer's verification (InspectOptions::storedForms)
};

struct ZipEntry {
  std::string name;                  // inside the archive
  std::filesystem::path source;      // file on disk, read by libzip when the archive is closed
  ZipStorage storage = ZipStorage::Deflate;
  // Instead of `source`: data compressed beforehand (in parallel, band by band), copied into the
  // archive without recompressing; `storage` says what it is.
  std::optional<StagedZipData> staged;
};

struct ZipMemoryEntry {
  std::string name;
  std::span<const std::uint8_t> data;  // must stay alive until writeZipFromMemory returns
  ZipStorage storage = ZipStorage::Deflate;
};

// The DOS timestamp of every entry (zip stores local time; this is noon, 1 January 2020 UTC).
inline constexpr long long kZipEntryTime = 1577880000;

// Writes a new zip holding `entries` in the given order; the bytes depend on nothing but the
// entries' contents, names and storage, and for staged entries their compressed bytes (fixed
// timestamps and attributes).
void writeZip(const std::filesystem::path& zipPath, const std::vector<ZipEntry>& entries);
// The same from memory (deflated by libzip with zlib).
void writeZipFromMemory(const std::filesystem::path& zipPath, const std::vector<ZipMemoryEntry>& entries);

}  // namespace rodfab::printer_profiles
