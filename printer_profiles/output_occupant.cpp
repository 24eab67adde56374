#include "printer_profiles/output_occupant.hpp"

#include "printer_profiles/job_archive.hpp"
#include "printer_profiles/job_reader.hpp"

#include "common/file_hasher.hpp"
#include "common/interrupt.hpp"
#include "common/xxh128.hpp"

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <zip.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;

namespace {

// A file as the manifest's "files" table records it: its length and checksum.
struct ListedFile {
  std::uint64_t bytes = 0;
  common::HashAlgorithm algorithm = common::HashAlgorithm::Xxh128;
  std::string digest;  // lowercase hex; empty when the row gives none
};

// Only what tells a rodfab job, read as SAX events (no document is built): the top-level "format" and
// the rows of the top-level "files" table. Stops at nesting deeper than a manifest has.
class ManifestSummary final : public nlohmann::json_sax<nlohmann::json> {
public:
  std::string format;
  std::map<std::string, ListedFile> files;

  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t value) override {
    if (row_ && depth_ == 3 && rowKey_ == "bytes") row_->bytes = value;
    return true;
  }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool string(string_t& value) override {
    if (depth_ == 1 && topKey_ == "format") format = value;
    if (row_ && depth_ == 3 && (rowKey_ == "xxh128" || rowKey_ == "sha256")) {
      row_->algorithm = rowKey_ == "xxh128" ? common::HashAlgorithm::Xxh128 : common::HashAlgorithm::Sha256;
      row_->digest = value;
    }
    return true;
  }
  bool start_object(std::size_t) override { return enter(); }
  bool start_array(std::size_t) override { return enter(); }
  bool key(string_t& name) override {
    if (depth_ == 1) topKey_ = name;
    else if (depth_ == 2 && inFiles_) row_ = &files[name];
    else if (depth_ == 3) rowKey_ = name;
    return true;
  }
  bool end_object() override { return leave(); }
  bool end_array() override { return leave(); }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override { return false; }

private:
  static constexpr int kMaxDepth = 16;  // a manifest nests 5 deep
  bool enter() {
    ++depth_;
    if (depth_ == 2) inFiles_ = topKey_ == "files";
    return depth_ <= kMaxDepth;
  }
  bool leave() {
    if (depth_ == 2) inFiles_ = false, row_ = nullptr;
    if (depth_ == 3) rowKey_.clear();
    --depth_;
    return true;
  }
  int depth_ = 0;
  std::string topKey_, rowKey_;
  bool inFiles_ = false;
  ListedFile* row_ = nullptr;  // the row being read (a node of `files`: its address is stable)
};

std::optional<ManifestSummary> summarizeManifest(const std::string& text) {
  ManifestSummary summary;
  if (!nlohmann::json::sax_parse(text, &summary) || summary.format != kJobFormat) return std::nullopt;
  return summary;
}

// An open file descriptor, closed on scope exit unless released.
struct Descriptor {
  int fd = -1;
  ~Descriptor() {
    if (fd >= 0) ::close(fd);
  }
  int release() { return std::exchange(fd, -1); }
};

// Up to `limit` bytes from `fd` (fewer at its end); nullopt when reading fails or more are there.
std::optional<std::string> readAtMost(int fd, std::size_t limit) {
  std::string text(std::min<std::size_t>(limit, 1 << 16) + 1, '\0');
  std::size_t got = 0;
  for (;;) {
    if (got == text.size()) {
      if (text.size() > limit) return std::nullopt;
      text.resize(std::min(limit + 1, text.size() * 2));
    }
    const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return std::nullopt;
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  text.resize(got);
  return text;
}

// Opens a regular file that must be the entry `st` describes: no link is followed, no pipe waited on.
int openSameFile(const fs::path& path, const struct stat& st) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  struct stat opened {};
  if (fd >= 0 && (::fstat(fd, &opened) != 0 || !S_ISREG(opened.st_mode) || opened.st_dev != st.st_dev || opened.st_ino != st.st_ino)) {
    ::close(fd);
    return -1;
  }
  return fd;
}

std::string inQuotes(const std::string& name) { return "'" + name + "'"; }

// The first entry of `folder` (below `prefix` in the job) that is not a regular file the manifest
// lists; previews/ is looked into. Stops at the first one, so a huge folder is not listed.
std::optional<std::string> firstStranger(const fs::path& folder, const std::string& prefix, const ManifestSummary& manifest) {
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = prefix + it->path().filename().string();
    const fs::file_status status = it->symlink_status(ec);
    if (ec) return name;
    if (name == kManifestName) continue;
    if (name == "previews" && prefix.empty() && fs::is_directory(status)) {
      if (auto inner = firstStranger(it->path(), "previews/", manifest)) return inner;
      continue;
    }
    if (!fs::is_regular_file(status) || !manifest.files.contains(name)) return name;
  }
  if (ec) return "an entry it cannot list (" + ec.message() + ")";
  return std::nullopt;
}

// Why `entry` is not the file the manifest's row for it records (a clause naming it), or nullopt when
// it is: its bytes are streamed (inflated from a zip) and hashed by the row's algorithm.
std::optional<std::string> changeIn(const JobReader& job, const JobEntry& entry, const ManifestSummary& manifest) {
  if (entry.kind == EntryKind::Directory || entry.name == kManifestName) return std::nullopt;
  const auto row = manifest.files.find(entry.name);
  if (entry.kind != EntryKind::File || row == manifest.files.end()) return inQuotes(entry.name) + " is not part of it";
  common::throwIfInterrupted();
  common::FileHasher hasher(row->second.algorithm);
  std::uint64_t bytes = 0;
  try {
    job.stream(entry, row->second.bytes, [&](std::span<const std::uint8_t> chunk) {
      hasher.update(chunk);
      bytes += chunk.size();
    });
  } catch (const EntryTooLarge&) {
    return inQuotes(entry.name) + " was changed since rodfab wrote it (longer than the " + std::to_string(row->second.bytes) +
           " bytes the manifest records)";
  } catch (const JobReadError& e) {
    return inQuotes(entry.name) + " cannot be read (" + std::string(e.what()) + ")";
  }
  if (bytes != row->second.bytes || row->second.digest.empty() || hasher.hex() != row->second.digest)
    return inQuotes(entry.name) + " was changed since rodfab wrote it (its length or checksum is not the one the manifest records)";
  return std::nullopt;
}

// The first file of the job (in the reader's order: the zip's, or sorted by name) that is not the file
// the manifest records: a job in which someone changed a file (a technician's notes added to
// report.html) holds their work, and is not replaced. Every file is read, on the caller's TBB arena:
// the 6-gigavoxel lattice job's 1.6 GB of layer images in ~0.5 s of two cores (README.md, "Replacing
// a job").
std::optional<std::string> firstChangedFile(const fs::path& path, const ManifestSummary& manifest) {
  std::unique_ptr<JobReader> job;
  try {
    job = openJobReader(path, manifest.files.size() + 2, 2);  // the manifest and previews/ besides the rows
  } catch (const JobReadError& e) {
    return std::string("the job cannot be read (") + e.what() + ")";
  }
  if (job->truncated()) return std::string("there are more entries than its manifest lists");
  const std::vector<JobEntry>& entries = job->entries();
  std::vector<std::optional<std::string>> changes(entries.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, entries.size()), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) changes[i] = changeIn(*job, entries[i], manifest);
  });
  for (std::optional<std::string>& change : changes)
    if (change) return std::move(change);
  return std::nullopt;
}

// A folder is a rodfab job when it holds a rodfab manifest and only regular files that manifest lists.
std::string examineFolder(const fs::path& path) {
  struct stat st {};
  const fs::path manifestPath = path / kManifestName;
  if (::lstat(manifestPath.c_str(), &st) != 0 || !S_ISREG(st.st_mode))
    return "a folder without a rodfab job manifest (" + std::string(kManifestName) + ")";
  Descriptor file{openSameFile(manifestPath, st)};
  const std::optional<std::string> text = file.fd >= 0 ? readAtMost(file.fd, kMaxManifestBytes) : std::nullopt;
  const std::optional<ManifestSummary> manifest = text ? summarizeManifest(*text) : std::nullopt;
  if (!manifest) return std::string("a folder whose ") + kManifestName + " is not a rodfab job manifest (" + kJobFormat + ")";
  if (auto name = firstStranger(path, "", *manifest))
    return "a folder holding a rodfab job and also " + inQuotes(*name) + ", which is not part of that job";
  if (auto change = firstChangedFile(path, *manifest)) return "a folder holding a rodfab job in which " + *change;
  return "";
}

// The first entry of the zip `za` that is neither its manifest nor a file that manifest lists (the
// zip's counterpart of firstStranger): a job zip to which someone added a file is not replaced.
std::optional<std::string> firstZipStranger(zip_t* za, const ManifestSummary& manifest) {
  const zip_int64_t entries = zip_get_num_entries(za, 0);
  for (zip_int64_t n = 0; n < entries; ++n) {
    const char* name = zip_get_name(za, static_cast<zip_uint64_t>(n), ZIP_FL_ENC_RAW);
    if (!name) return "an entry whose name cannot be read";
    if (std::string_view(name) != kManifestName && !manifest.files.contains(name)) return std::string(name);
  }
  return std::nullopt;
}

// A comment in the zip `za` (rodfab writes none): a note someone added to the archive or to one of
// its entries (`zip -z`, `zip -c`), which replacing the job would lose.
std::optional<std::string> firstZipComment(zip_t* za) {
  int archiveLength = 0;
  if (zip_get_archive_comment(za, &archiveLength, ZIP_FL_ENC_RAW) && archiveLength > 0) return std::string("the archive");
  const zip_int64_t entries = zip_get_num_entries(za, 0);
  for (zip_int64_t n = 0; n < entries; ++n) {
    zip_uint32_t length = 0;
    if (zip_file_get_comment(za, static_cast<zip_uint64_t>(n), &length, ZIP_FL_ENC_RAW) && length > 0) {
      const char* name = zip_get_name(za, static_cast<zip_uint64_t>(n), ZIP_FL_ENC_RAW);
      return "its entry " + inQuotes(name ? name : "?");
    }
  }
  return std::nullopt;
}

// The manifest entry's text, empty when it is missing, too large or unreadable.
std::string zipManifestText(zip_t* za) {
  std::string text;
  const zip_int64_t index = zip_name_locate(za, kManifestName, 0);
  zip_stat_t zs;
  zip_file_t* zf = nullptr;
  if (index >= 0 && zip_stat_index(za, static_cast<zip_uint64_t>(index), 0, &zs) == 0 && (zs.valid & ZIP_STAT_SIZE) &&
      zs.size <= kMaxManifestBytes && (zf = zip_fopen_index(za, static_cast<zip_uint64_t>(index), 0))) {
    text.resize(zs.size);
    if (zip_fread(zf, text.data(), zs.size) != static_cast<zip_int64_t>(zs.size)) text.clear();
    zip_fclose(zf);
  }
  return text;
}

// A zip is a rodfab job when its first entry is manifest.json (the writer's fixed order) of the job
// format and every other entry is a file that manifest lists. The local header is looked at first
// (46 bytes), so a large foreign zip is not read at all.
std::string examineZip(const fs::path& path, const struct stat& st) {
  Descriptor file{openSameFile(path, st)};
  if (file.fd < 0) return std::string("a file that cannot be opened (") + std::strerror(errno) + ")";
  constexpr std::size_t kHeader = 30;
  const std::string_view wanted = kManifestName;
  unsigned char head[kHeader + 13] = {};
  const ssize_t got = ::pread(file.fd, head, sizeof head, 0);
  if (got < 4 || std::memcmp(head, "PK\x03\x04", 4) != 0)
    return got == 0 ? "an empty file" : "a file that is not a zip archive";
  const unsigned nameLength = head[26] | (head[27] << 8);
  if (got != static_cast<ssize_t>(sizeof head) || nameLength != wanted.size() ||
      std::string_view(reinterpret_cast<const char*>(head + kHeader), wanted.size()) != wanted)
    return "a zip archive whose first entry is not a rodfab job manifest";
  int error = 0;
  zip_t* za = zip_fdopen(file.fd, 0, &error);
  if (!za) return "a zip archive that cannot be read";
  file.release();  // libzip owns it now
  const std::optional<ManifestSummary> manifest = summarizeManifest(zipManifestText(za));
  const std::optional<std::string> stranger = manifest ? firstZipStranger(za, *manifest) : std::nullopt;
  const std::optional<std::string> comment = manifest ? firstZipComment(za) : std::nullopt;
  zip_discard(za);
  if (!manifest) return std::string("a zip archive whose ") + kManifestName + " is not a rodfab job manifest (" + kJobFormat + ")";
  if (stranger) return "a zip archive holding a rodfab job and also " + inQuotes(*stranger) + ", which is not part of that job";
  if (comment) return "a zip archive holding a rodfab job with a comment added to " + *comment + " (rodfab writes none)";
  if (auto change = firstChangedFile(path, *manifest)) return "a zip archive holding a rodfab job in which " + *change;
  return "";
}

OutputOccupant examineAfresh(const fs::path& path) {
  OutputOccupant out;
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return out;
    out.kind = OutputOccupant::Kind::Other;
    out.description = std::string("an entry that cannot be examined (") + std::strerror(errno) + ")";
    return out;
  }
  out.device = static_cast<std::uint64_t>(st.st_dev);
  out.inode = static_cast<std::uint64_t>(st.st_ino);
  if (S_ISDIR(st.st_mode)) out.description = examineFolder(path);
  else if (S_ISREG(st.st_mode)) out.description = examineZip(path, st);
  else if (S_ISLNK(st.st_mode)) out.description = "a symbolic link (never followed or replaced)";
  else if (S_ISFIFO(st.st_mode)) out.description = "a named pipe";
  else if (S_ISSOCK(st.st_mode)) out.description = "a socket";
  else out.description = "a device file";
  out.kind = out.description.empty() ? OutputOccupant::Kind::RodfabJob : OutputOccupant::Kind::Other;
  if (out.kind == OutputOccupant::Kind::RodfabJob)
    out.description = S_ISDIR(st.st_mode) ? "a rodfab job folder" : "a rodfab job archive";
  return out;
}

// The statuses of a job's entries, hashed, and whether every change they record is settled: older than
// the file system's timestamps can blur (a change within the same coarse clock tick as the one before
// it leaves the times as they were; git's index meets the same with its "racily clean" entries).
struct StatusStamp {
  std::string hash;
  bool settled = true;
};

// One entry's status added to `record`: whatever a write, a rename or a replacement changes. Every
// write sets a file's change time (st_ctim), which no user can set back.
void addStatus(std::string& record, bool& settled, const std::string& name, const struct stat& st) {
  const std::uint64_t fields[] = {std::uint64_t(st.st_dev), std::uint64_t(st.st_ino), std::uint64_t(st.st_mode), std::uint64_t(st.st_size),
                                  std::uint64_t(st.st_mtim.tv_sec), std::uint64_t(st.st_mtim.tv_nsec),
                                  std::uint64_t(st.st_ctim.tv_sec), std::uint64_t(st.st_ctim.tv_nsec)};
  record += name;
  record.push_back('\0');
  record.append(reinterpret_cast<const char*>(fields), sizeof fields);
  constexpr std::int64_t kSettledSeconds = 2;
  settled = settled && std::int64_t(st.st_ctim.tv_sec) + kSettledSeconds < std::int64_t(std::time(nullptr));
}

// The status of the entry at `path` and, for a folder, of every entry in it and in its previews/
// folder, sorted by name: it changes whenever anything in a job does. nullopt when a status cannot be
// read.
std::optional<StatusStamp> statusStamp(const fs::path& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return std::nullopt;
  StatusStamp stamp;
  std::string record;
  addStatus(record, stamp.settled, "", st);
  if (S_ISDIR(st.st_mode)) {
    std::vector<std::pair<std::string, struct stat>> entries;
    for (const fs::path& folder : {path, path / "previews"}) {
      std::error_code ec;
      for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
        if (::lstat(it->path().c_str(), &st) != 0) return std::nullopt;
        entries.emplace_back(it->path().lexically_relative(path).string(), st);
      }
      if (ec && ec != std::errc::no_such_file_or_directory && ec != std::errc::not_a_directory) return std::nullopt;
    }
    std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& [name, status] : entries) addStatus(record, stamp.settled, name, status);
  }
  stamp.hash = common::xxh128Hex(record);
  return stamp;
}

}  // namespace

// A job is examined up to three times a run (the command's early check, the writer's, the commit's),
// and reading every file of a 6-gigavoxel job takes ~0.5 s of both cores: a job found whole is
// remembered with its status stamp, and found again without reading while the stamp is the same and
// settled (a job changed in the last seconds is read again every time).
OutputOccupant examineOutput(const fs::path& path) {
  static std::mutex mutex;
  static std::map<std::string, std::pair<std::string, OutputOccupant>> jobsFound;  // by path: stamp, finding
  const std::optional<StatusStamp> stamp = statusStamp(path);
  if (stamp && stamp->settled) {
    const std::lock_guard lock(mutex);
    const auto found = jobsFound.find(path.string());
    if (found != jobsFound.end() && found->second.first == stamp->hash) return found->second.second;
  }
  const OutputOccupant out = examineAfresh(path);
  const std::optional<StatusStamp> after = stamp ? statusStamp(path) : std::nullopt;
  if (out.kind == OutputOccupant::Kind::RodfabJob && after && after->settled && after->hash == stamp->hash) {
    const std::lock_guard lock(mutex);
    jobsFound[path.string()] = {stamp->hash, out};
  }
  return out;
}

}  // namespace rodfab::printer_profiles
