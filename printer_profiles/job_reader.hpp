// Internal to printer_profiles/ (used by `inspect`): reading a job that may be hostile. Nothing the job
// says is trusted: entries are listed as found (regular files, folders, and everything else flagged, never
// opened), files are streamed in chunks with a hard cap on the bytes they may produce, and no path named
// inside the job is ever followed (folder jobs are walked with openat and O_NOFOLLOW, files opened with
// O_NONBLOCK so a FIFO cannot block, and checked to be the regular file that was listed).
#pragma once

#include "printer_profiles/job_archive.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rodfab::printer_profiles {

enum class EntryKind {
  File,       // a regular file (zip: a file entry stored or deflated, not encrypted)
  Directory,  // a folder (zip: a name ending in '/')
  Other,      // anything else: symbolic link, FIFO, device, socket, encrypted or oddly compressed entry
};

struct JobEntry {
  std::string name;                // '/' separated, relative to the job; folders end in '/'
  EntryKind kind = EntryKind::File;
  std::uint64_t declaredBytes = 0; // what the archive or file system says (never trusted for allocation)
  std::string otherWhat;           // EntryKind::Other: what it is, e.g. "a symbolic link"
  std::uint64_t index = 0;         // reader's own handle (zip index, or position in the folder walk)
};

// A file that produced more bytes than its cap allows (a deflate bomb, or a file far too large).
class EntryTooLarge : public JobReadError {
public:
  EntryTooLarge(const std::string& message, std::uint64_t cap) : JobReadError(message), cap_(cap) {}
  std::uint64_t cap() const { return cap_; }

private:
  std::uint64_t cap_;
};

// What a zip archive's directory records for an entry (JobReader::streamStored).
struct StoredEntryInfo {
  bool deflated = false;     // else stored as it is
  std::uint64_t size = 0;    // of the contents
  std::uint32_t crc32 = 0;   // of the contents
};

class JobReader {
public:
  virtual ~JobReader() = default;
  const std::filesystem::path& path() const { return path_; }
  ArchiveFormat format() const { return format_; }
  // Every entry found, in archive order (zip) or sorted by name (folder); at most the `maxEntries` given
  // to openJobReader (see truncated()).
  const std::vector<JobEntry>& entries() const { return entries_; }
  // True when the job holds more entries than were listed.
  bool truncated() const { return truncated_; }
  // Streams a File entry to `sink` in chunks of at most 64 KiB, in order. Throws EntryTooLarge as soon as
  // more than `maxBytes` bytes come out, JobReadError (naming the entry) when it cannot be read, is
  // damaged (zip CRC) or was swapped for something else since it was listed. Safe to call from several
  // threads at once.
  virtual void stream(const JobEntry& entry, std::uint64_t maxBytes,
                      const std::function<void(std::span<const std::uint8_t>)>& sink) const = 0;

  // Zip jobs: streams a File entry's bytes as the archive holds them (deflated or stored, not decoded and
  // not checked against the CRC: the caller knows what they must be), in order, and returns what the
  // archive's directory records for the entry. Throws EntryTooLarge past `maxBytes`, JobReadError as
  // stream() does, and for folder jobs (their files have no other form). Safe from several threads.
  virtual StoredEntryInfo streamStored(const JobEntry& entry, std::uint64_t maxBytes,
                                       const std::function<void(std::span<const std::uint8_t>)>& sink) const;

  // stream() into memory (at most maxBytes are ever held).
  Bytes read(const JobEntry& entry, std::uint64_t maxBytes) const;

  // The entry `name` at the top of the job (no '/' in it), looked up by name where the listing was
  // truncated before reaching it (a folder lists in no particular order once it holds more than
  // maxEntries), and classified as a listed entry would be; never followed. nullopt when there is
  // none. Not safe while other threads read from the reader.
  virtual std::optional<JobEntry> findUnlisted(const std::string& name) = 0;

protected:
  JobReader(std::filesystem::path path, ArchiveFormat format, std::size_t maxEntries)
      : path_(std::move(path)), format_(format), maxEntries_(maxEntries) {}
  // Whether the listing has room for another entry; once it has not, truncated() is true and the
  // reader lists no more.
  bool roomForEntry() {
    if (entries_.size() >= maxEntries_) truncated_ = true;
    return !truncated_;
  }
  std::size_t maxEntries() const { return maxEntries_; }
  // Lists `entry` (the caller made sure of roomForEntry()).
  void addEntry(JobEntry entry) { entries_.push_back(std::move(entry)); }

private:
  std::filesystem::path path_;
  ArchiveFormat format_;
  std::size_t maxEntries_;
  bool truncated_ = false;
  std::vector<JobEntry> entries_;
};

// A folder is read as a folder job, a regular file as a zip archive; anything else (FIFO, device, a
// missing path) is refused with JobReadError before it is read. The path itself is the caller's (it may
// be a symbolic link); nothing inside the job is followed. Folder jobs are walked at most `maxDepth`
// folders deep.
std::unique_ptr<JobReader> openJobReader(const std::filesystem::path& job, std::size_t maxEntries, int maxDepth);

// Why an entry name is unsafe to unpack on some platform (Linux, macOS, Windows), or nullopt when it is
// safe: empty, absolute, '..' or '.' components, empty components, backslashes, drive letters and other
// ':', characters Windows refuses (<>"|?*), control characters, anything but printable ASCII, a component
// ending in a dot or a space, or a Windows device name (CON, NUL, COM1, ...). A trailing '/' (a folder
// entry) is allowed.
std::optional<std::string> unsafeEntryName(std::string_view name);

// `name` with every byte that is not printable ASCII written as \xNN, cut to 200 characters: safe to put
// in a message shown on a terminal.
std::string printableName(std::string_view name);

}  // namespace rodfab::printer_profiles
