#include "common/output_file.hpp"

#include "common/interrupt.hpp"
#include "common/xxh128.hpp"

#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstdint>
#include <cstring>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <system_error>

namespace rodfab::common {

namespace fs = std::filesystem;

namespace {

std::string quoted(const fs::path& p) { return p.string(); }

bool sameFile(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  if (fs::equivalent(a, b, ec)) return true;
  return fs::weakly_canonical(a, ec) == fs::weakly_canonical(b, ec) && !ec;
}

void renameInto(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::rename(from, to, ec);
  if (ec) throw std::runtime_error(quoted(to) + ": cannot move the finished file into place: " + ec.message());
}

// What checkOutputPath found at each output path it allowed (the entry's status, or none), so that a
// commit can tell a file put there, replaced or changed while the command worked: a person's, which
// the commit must not replace.
struct FoundStatus {
  bool exists = false;
  std::uint64_t device = 0, inode = 0, size = 0;
  std::int64_t changedSeconds = 0, changedNanoseconds = 0;
  bool operator==(const FoundStatus&) const = default;
};
std::mutex foundMutex;
std::map<fs::path, FoundStatus>& foundAtCheck() {
  static auto* found = new std::map<fs::path, FoundStatus>;  // outlives static destruction
  return *found;
}
fs::path outputKey(const fs::path& output) { return fs::absolute(output).lexically_normal(); }
FoundStatus statusOf(const fs::path& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return {};
  return {true, std::uint64_t(st.st_dev), std::uint64_t(st.st_ino), std::uint64_t(st.st_size), std::int64_t(st.st_ctim.tv_sec),
          std::int64_t(st.st_ctim.tv_nsec)};
}

// Throws when `output` is not as checkOutputPath found it (outputs it never checked pass).
void requireAsChecked(const fs::path& output) {
  const std::lock_guard lock(foundMutex);
  const auto found = foundAtCheck().find(outputKey(output));
  if (found == foundAtCheck().end() || statusOf(output) == found->second) return;
  throw std::runtime_error(quoted(output) + (found->second.exists ? ": was changed or replaced" : ": was created") +
                           " while rodfab was working; it was left as it is and nothing was written there");
}

void recordAsChecked(const fs::path& output) {
  const std::lock_guard lock(foundMutex);
  foundAtCheck()[outputKey(output)] = statusOf(output);
}

void checkExisting(const fs::path& output, const fs::file_status& status, const OutputPolicy& policy) {
  if (fs::is_directory(status))
    throw std::runtime_error(quoted(output) + ": is a folder; the " + policy.what + " needs a file name");
  if (fs::is_symlink(status))
    throw std::runtime_error(quoted(output) + ": is a symbolic link; rodfab does not write through links");
  if (!fs::is_regular_file(status))
    throw std::runtime_error(quoted(output) + ": exists and is not a regular file; rodfab will not replace it");
  if (!policy.replaceExisting)
    throw std::runtime_error(quoted(output) + ": already exists; use " + policy.howToReplace + " to replace it");
  if (policy.isOurs && !policy.isOurs(output))
    throw std::runtime_error(quoted(output) + ": exists and is not a " + policy.what +
                             " written by rodfab (or was changed since); rodfab replaces only its own files (choose another name)");
}

bool processAlive(long pid) { return pid > 0 && (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM); }

// The pid in a hidden name ".NAME<tag>PID-N" (tag ".rodfab-tmp-" or ".rodfab-old-"), or 0 when the
// name is not one of ours.
long hiddenOwner(const std::string& name, const std::string& tag) {
  const auto at = name.rfind(tag);
  if (name.empty() || name[0] != '.' || at == std::string::npos) return 0;
  const std::string tail = name.substr(at + tag.size());
  const auto dash = tail.find('-');
  const auto digits = [](const std::string& t) {
    return !t.empty() && t.find_first_not_of("0123456789") == std::string::npos && t.size() < 12;
  };
  if (dash == std::string::npos || !digits(tail.substr(0, dash)) || !digits(tail.substr(dash + 1))) return 0;
  return std::strtol(tail.c_str(), nullptr, 10);
}

// Temporaries that earlier runs killed outright (SIGKILL, power) left in `final`'s folder, whatever
// their final name: hidden, ours by name, tagged with a pid that no longer runs.
void removeStaleTemporaries(const fs::path& final) {
  std::error_code ec;
  const fs::path folder = final.parent_path().empty() ? fs::path(".") : final.parent_path();
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const long pid = hiddenOwner(it->path().filename().string(), ".rodfab-tmp-");
    std::error_code ignored;
    if (pid > 0 && pid != ::getpid() && !processAlive(pid) && it->is_regular_file(ignored)) fs::remove(it->path(), ignored);
  }
}

}  // namespace

std::vector<fs::path> leftoverPreviousVersions(const fs::path& given) {
  const fs::path output = given.has_filename() ? given : given.parent_path();  // a job folder given as "job/"
  std::vector<fs::path> kept;
  const fs::path folder = output.parent_path().empty() ? fs::path(".") : output.parent_path();
  std::string prefix = ".";  // appended piecewise: GCC 12 warns falsely (-Wrestrict) on "." + string
  prefix.append(output.filename().string()).append(".rodfab-old-");
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!name.starts_with(prefix)) continue;
    const long pid = hiddenOwner(name, ".rodfab-old-");
    if (pid == 0 || pid == ::getpid() || processAlive(pid)) continue;  // the tag found last is the prefix's: PID-N has none
    std::error_code ignored;
    // Killed between keeping the link and the commit's rename: the same file as the output, no data of its own.
    if (fs::is_regular_file(it->symlink_status(ignored)) && fs::equivalent(it->path(), output, ignored)) {
      fs::remove(it->path(), ignored);
      continue;
    }
    kept.push_back(it->path());
  }
  std::sort(kept.begin(), kept.end());
  return kept;
}

void checkOutputPath(const fs::path& output, const std::vector<fs::path>& inputs, const OutputPolicy& policy) {
  if (output.empty()) throw std::runtime_error("no output path given for the " + policy.what);
  for (const fs::path& input : inputs)
    if (!input.empty() && sameFile(output, input))
      throw std::runtime_error(quoted(output) + ": is also an input of this command; write the " + policy.what +
                               " to another file");
  std::error_code ec;
  const fs::file_status status = fs::symlink_status(output, ec);
  if (fs::exists(status)) checkExisting(output, status, policy);
  const fs::path parent = fs::absolute(output).parent_path();
  if (!fs::is_directory(parent, ec))
    throw std::runtime_error(quoted(output) + ": cannot write: " + quoted(parent) +
                             (fs::exists(parent, ec) ? " is not a folder" : ": the folder does not exist"));
  checkOutputNameLength(output);
  recordAsChecked(output);
}

void checkOutputNameLength(const fs::path& output) {
  const fs::path absolute = fs::absolute(output);
  const std::size_t name = absolute.filename().string().size();
  const long limit = ::pathconf(absolute.parent_path().c_str(), _PC_NAME_MAX);
  const std::size_t nameMax = limit > 0 ? static_cast<std::size_t>(limit) : NAME_MAX;
  if (name + kHiddenNameExtraBytes > nameMax)
    throw std::runtime_error(quoted(output) + ": the file name is " + std::to_string(name) + " bytes long; rodfab writes it first under a hidden name up to " +
                             std::to_string(kHiddenNameExtraBytes) + " bytes longer, and this folder's file system allows names of at most " +
                             std::to_string(nameMax) + " bytes: use a name of at most " +
                             std::to_string(nameMax > kHiddenNameExtraBytes ? nameMax - kHiddenNameExtraBytes : 0) + " bytes");
  // The hidden name is made beside the path as given (relative paths stay relative).
  if (output.string().size() + kHiddenNameExtraBytes >= PATH_MAX)
    throw std::runtime_error(quoted(output) + ": the path is " + std::to_string(output.string().size()) +
                             " bytes long; with the hidden name rodfab writes first it would exceed the system's limit of " +
                             std::to_string(PATH_MAX - 1) + " bytes: use a shorter path");
}

bool fileStartsWith(const fs::path& file, std::string_view prefix, std::string_view marker, std::size_t scanBytes) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return false;
  struct stat st {};
  std::string head;
  if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode)) {
    head.resize(std::max(prefix.size(), scanBytes));
    const ssize_t n = ::read(fd, head.data(), head.size());
    head.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
  }
  ::close(fd);
  if (!std::string_view(head).starts_with(prefix)) return false;
  return marker.empty() || head.find(marker) != std::string::npos;
}

namespace {

std::string sealLinePrefix() { return std::string("{\n  \"") + kWrittenByKey + "\": \"rodfab, xxh128 "; }
constexpr std::string_view kSealLineEnd = "\",\n";
constexpr std::size_t kDigestDigits = 32;

}  // namespace

std::optional<std::string> readRegularFileAtMost(const fs::path& file, std::size_t maxBytes) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) return std::nullopt;
  struct stat st {};
  std::optional<std::string> text;
  if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && static_cast<std::uint64_t>(st.st_size) <= maxBytes) {
    text.emplace(static_cast<std::size_t>(st.st_size) + 1, '\0');  // one more: a file that grew is refused
    std::size_t got = 0;
    for (ssize_t n; got < text->size() && (n = ::read(fd, text->data() + got, text->size() - got)) != 0;) {
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) break;
      got += static_cast<std::size_t>(n);
    }
    if (got == static_cast<std::size_t>(st.st_size)) text->resize(got);
    else text.reset();
  }
  ::close(fd);
  return text;
}

std::string sealJsonObject(std::string_view members) {
  return sealLinePrefix() + common::xxh128Hex(members) + std::string(kSealLineEnd) + std::string(members);
}

bool isSealedJsonObject(const fs::path& file, std::size_t maxBytes) {
  const std::optional<std::string> text = readRegularFileAtMost(file, maxBytes);
  const std::string prefix = sealLinePrefix();
  const std::size_t bodyStart = prefix.size() + kDigestDigits + kSealLineEnd.size();
  if (!text || text->size() < bodyStart || !text->starts_with(prefix)) return false;
  const std::string_view view(*text);
  const std::string_view digest = view.substr(prefix.size(), kDigestDigits);
  return view.substr(prefix.size() + kDigestDigits, kSealLineEnd.size()) == kSealLineEnd && isXxh128Hex(digest) &&
         xxh128Hex(view.substr(bodyStart)) == digest;
}

AtomicOutput::AtomicOutput(fs::path final) : final_(std::move(final)) {
  static std::atomic<int> counter{0};
  const fs::path name = final_.filename();
  if (name.empty()) throw std::runtime_error(quoted(final_) + ": expected a file name");
  removeStaleTemporaries(final_);
  std::string hidden = ".";  // appended piecewise: GCC 12 warns falsely (-Wrestrict) on "." + string
  hidden.append(name.string()).append(".rodfab-tmp-").append(std::to_string(::getpid()));
  hidden.append("-").append(std::to_string(counter++));
  temporary_ = final_.parent_path() / hidden;
  registerCleanup(temporary_);
}

AtomicOutput::~AtomicOutput() {
  if (committed_) return;
  std::error_code ignored;
  fs::remove(temporary_, ignored);
  unregisterCleanup(temporary_);
}

namespace {

// fsync or syncfs on `path` opened with `flags`: 0, or the errno of what failed (opening or
// flushing). A file system that cannot sync (EINVAL, EROFS) counts as flushed.
int flush(const fs::path& path, int flags, bool wholeFileSystem) {
  const int fd = ::open(path.c_str(), flags | O_CLOEXEC);
  if (fd < 0) return errno;
  const int result = wholeFileSystem ? ::syncfs(fd) : ::fsync(fd);
  const int error = errno;
  ::close(fd);
  return result == 0 || error == EINVAL || error == EROFS ? 0 : error;
}

}  // namespace

void syncToDevice(const fs::path& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) throw std::runtime_error(quoted(path) + ": cannot flush it to disk (" + std::strerror(errno) + ")");
  const int error = S_ISDIR(st.st_mode) ? flush(path, O_RDONLY | O_DIRECTORY, true) : flush(path, O_RDONLY, false);
  // EACCES: written but not readable by us (a umask), left to the kernel's writeback.
  if (error != 0 && error != EACCES)
    throw std::runtime_error(quoted(path) + ": cannot flush it to disk (" + std::strerror(error) + "); nothing was replaced");
}

void startWriteback(const fs::path& file) noexcept {
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return;
  ::sync_file_range(fd, 0, 0, SYNC_FILE_RANGE_WRITE);
  ::close(fd);
}

bool syncFolderEntries(const fs::path& folder) {
  return flush(folder.empty() ? fs::path(".") : folder, O_RDONLY | O_DIRECTORY, false) == 0;
}

void AtomicOutput::commit() {
  syncToDevice(temporary_);  // the data is on disk before the name points at it (an error replaces nothing)
  requireAsChecked(final_);
  commitRegistered(temporary_, final_, renameInto);
  committed_ = true;
  syncFolderEntries(final_.parent_path());
  recordAsChecked(final_);  // a second commit of the same output replaces this one
}

void writeFileAtomically(const fs::path& file, std::string_view bytes) {
  AtomicOutput out(file);
  const int fd = ::open(out.temporary().c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error(quoted(file) + ": cannot write there (" + std::strerror(errno) + ")");
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = std::strerror(errno);
      ::close(fd);
      throw std::runtime_error(quoted(file) + ": write failed (" + why + ")");
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) throw std::runtime_error(quoted(file) + ": write failed (" + std::strerror(errno) + ")");
  out.commit();
}

}  // namespace rodfab::common
