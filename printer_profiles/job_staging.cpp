#include "printer_profiles/job_staging.hpp"

#include "common/interrupt.hpp"
#include "common/output_file.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <charconv>
#include <csignal>
#include <cstdio>  // renameat2, RENAME_EXCHANGE, RENAME_NOREPLACE (glibc 2.28)
#include <cstring>
#include <fstream>
#include <limits>
#include <set>
#include <stdexcept>
#include <string_view>
#include <system_error>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;

namespace {

constexpr const char* kLockName = ".lock";

bool processAlive(long pid) { return pid > 0 && (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM); }

// Whether the staging folder's writer is gone: its lock file is free (flock dies with its holder, so
// a reused pid cannot fool it). Folders without a lock file (older versions, or a writer between
// mkdir and locking) are judged by their pid.
bool writerGone(const fs::path& folder, long pid) {
  const int fd = ::open((folder / kLockName).c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return errno == ENOENT && !processAlive(pid);
  const bool free = ::flock(fd, LOCK_EX | LOCK_NB) == 0;
  const bool unsupported = !free && errno != EWOULDBLOCK;
  ::close(fd);  // a later writer cannot take this name: names carry live pids
  return free || (unsupported && !processAlive(pid));
}

// Linux renameat2: swap two names in one step, or rename without replacing. False when the file
// system does not offer it (the caller falls back); other errors throw, naming both paths (EEXIST for
// RENAME_NOREPLACE: the target appeared, said as such).
bool renameWith(const fs::path& from, const fs::path& to, unsigned flags) {
  if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), flags) == 0) return true;
  if (errno == EINVAL || errno == ENOSYS || errno == ENOTSUP) return false;
  if (errno == EEXIST && (flags & RENAME_NOREPLACE))
    throw std::runtime_error(to.string() + ": appeared while the job was being written; it was left as it is");
  throw std::system_error(errno, std::generic_category(), "cannot rename " + from.string() + " to " + to.string());
}

void renameOrThrow(const fs::path& from, const fs::path& to) {
  if (::rename(from.c_str(), to.c_str()) != 0)
    throw std::system_error(errno, std::generic_category(), "cannot rename " + from.string() + " to " + to.string());
}

}  // namespace

void writeFile(const fs::path& path, std::span<const std::uint8_t> data) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
  out.close();
  if (!out) throw std::runtime_error(path.string() + ": cannot write (disk full or no permission?)");
}

// ".NAME.rodfab-partial-PID-N" for the target NAME and this process.
fs::path stagingPath(const fs::path& target, long n) {
  std::string name(".");  // appended piece by piece (GCC 12 warns wrongly about "." + std::string)
  name += target.filename().string();
  name += kPartialTag;
  name += std::to_string(::getpid());
  name += '-';
  name += std::to_string(n);
  return target.parent_path() / name;
}

// ".NAME.rodfab-partial-PID-N" (this version's staging folders), and the names older versions left:
// ".NAME.rodfab-partial-PID-N.zip" and ".NAME.rodfab-partial-PID-old". Returns the PID, or 0 when
// `name` is not exactly one of these.
long stagingPid(const std::string& name) {
  const std::size_t tag = name.rfind(kPartialTag);
  if (name.size() < 2 || name[0] != '.' || tag == std::string::npos || tag < 2) return 0;
  std::string_view rest = std::string_view(name).substr(tag + std::strlen(kPartialTag));
  long pid = 0;
  const auto [end, ec] = std::from_chars(rest.data(), rest.data() + rest.size(), pid);
  if (ec != std::errc() || end == rest.data() || pid <= 0 || pid > std::numeric_limits<pid_t>::max()) return 0;
  rest.remove_prefix(static_cast<std::size_t>(end - rest.data()));
  if (rest == "-old") return pid;
  if (!rest.starts_with('-')) return 0;
  rest.remove_prefix(1);
  if (rest.ends_with(".zip")) rest.remove_suffix(4);
  const bool digits = !rest.empty() && rest.find_first_not_of("0123456789") == std::string_view::npos;
  return digits ? pid : 0;
}

namespace {

// Without RENAME_EXCHANGE the commit moves the job it replaces into its staging folder ("replaced")
// before renaming the new one into place: a writer killed between the two left the output's name
// empty and the only copy of the old job in a folder this function removed. It goes back under its
// name, or, the name taken since, beside it as a previous version (`.NAME.rodfab-old-PID-N`, which
// the commands report and never remove). False when it could be neither: the folder must then stay.
bool recoverReplacedJob(const fs::path& staging, long pid) {
  const fs::path replaced = staging / "replaced";
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(replaced, ec))) return true;
  const std::string name = staging.filename().string();
  const std::string output = name.substr(1, name.rfind(kPartialTag) - 1);
  const fs::path home = staging.parent_path() / output;
  if (::renameat2(AT_FDCWD, replaced.c_str(), AT_FDCWD, home.c_str(), RENAME_NOREPLACE) == 0) return true;
  // Without RENAME_NOREPLACE (NFS refuses renameat2's flags): a plain rename onto a name found free.
  if ((errno == EINVAL || errno == ENOSYS || errno == ENOTSUP) && !fs::exists(fs::symlink_status(home, ec)) &&
      ::rename(replaced.c_str(), home.c_str()) == 0)
    return true;
  for (int n = 0; n < 1000; ++n) {
    const fs::path kept = common::previousVersionName(home, pid, n);
    if (fs::exists(fs::symlink_status(kept, ec))) continue;
    return ::rename(replaced.c_str(), kept.c_str()) == 0;
  }
  return false;
}

}  // namespace

namespace {

// Whether every entry of `folder` is one a staging folder holds (this version's, or "previews" of older
// ones'): a folder named like one that holds anything else is someone's, whatever its name says (a
// user's ".thesis.zip.rodfab-partial-99999-0" holding thesis.txt was removed with it).
bool holdsOnlyStaging(const fs::path& folder) {
  static const std::set<std::string> kOurs = {kLockName,  ".lock-init", "job",      "job.zip", "job.zip.part",
                                              "layers.bin", "replaced",   "withdrawn", "previews"};
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec))
    if (!kOurs.contains(it->path().filename().string())) return false;
  return !ec;
}

}  // namespace

// Leftovers of writers that died (killed, crashed) in `folder`, whatever job they were writing: only
// entries named exactly like staging folders and holding only what those hold (or older versions'
// temporary zips, "....zip"), only when their writer is gone; a link is never followed. A job such a
// writer had moved aside to replace it is recovered first (recoverReplacedJob).
void removeDeadStaging(const fs::path& folder) {
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const long pid = stagingPid(name);
    if (!pid) continue;
    std::error_code statusError;
    const fs::file_status status = it->symlink_status(statusError);
    if (statusError) continue;
    std::error_code ignored;
    if (fs::is_directory(status) && holdsOnlyStaging(it->path()) && writerGone(it->path(), pid)) {
      if (recoverReplacedJob(it->path(), pid)) fs::remove_all(it->path(), ignored);
    }
    else if (fs::is_regular_file(status) && name.ends_with(".zip") && !processAlive(pid)) fs::remove(it->path(), ignored);
  }
}

std::string refusal(const fs::path& target, const OutputOccupant& occupant) {
  return target.string() + ": is " + occupant.description +
         "; rodfab replaces only its own jobs (even with --force), so it was left as it is: choose another output";
}

Staging::Staging(const fs::path& target) {
  static std::atomic<int> counter{0};
  const fs::path parent = target.parent_path();
  for (int attempt = 0;; ++attempt) {
    root_ = stagingPath(target, counter++);
    if (::mkdir(root_.c_str(), 0777) == 0) break;
    if (errno != EEXIST || attempt == 100) fail(parent, std::strerror(errno), false);
  }
  common::registerCleanup(root_);  // removed on interrupt or a fatal error too (common/interrupt.hpp)
  std::error_code ec;
  fs::create_directories(files() / "previews", ec);
  if (ec) fail(parent, ec.message(), true);
  lock();
}

void Staging::remove() {
  std::error_code ec;
  if (!root_.empty()) {
    fs::remove_all(root_, ec);
    common::unregisterCleanup(root_);
  }
  root_.clear();
  if (lockFd_ >= 0) ::close(lockFd_);
  lockFd_ = -1;
}

void Staging::fail(const fs::path& parent, const std::string& why, bool created) {
  std::error_code ignored;
  if (created) fs::remove_all(root_, ignored);
  root_.clear();
  throw std::runtime_error(parent.string() + ": cannot write the job there (" + why + ")");
}

// Locked under a name nobody checks, then renamed: whoever finds ".lock" finds it locked while we live.
void Staging::lock() {
  const fs::path initial = root_ / ".lock-init";
  lockFd_ = ::open(initial.c_str(), O_RDWR | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
  if (lockFd_ < 0) fail(root_.parent_path(), std::strerror(errno), true);
  if (::flock(lockFd_, LOCK_EX | LOCK_NB) == 0) {
    if (::rename(initial.c_str(), (root_ / kLockName).c_str()) != 0) fail(root_.parent_path(), std::strerror(errno), true);
    return;
  }
  // A file system without flock: the folder goes by its pid alone, like older versions' folders.
  ::close(lockFd_);
  lockFd_ = -1;
  ::unlink(initial.c_str());
}

Commit commitJob(const fs::path& built, const fs::path& target, bool force, const Staging& staging) {
  // On the device before a name points at it: after a power loss the name holds the whole job, or the
  // old one (a zip: its data; a folder: its file system, in one flush); an I/O error replaces nothing.
  common::syncToDevice(built);
  Commit c;
  struct stat st {};
  if (::lstat(built.c_str(), &st) != 0) throw std::system_error(errno, std::generic_category(), built.string());
  c.device = static_cast<std::uint64_t>(st.st_dev);
  c.inode = static_cast<std::uint64_t>(st.st_ino);
  const OutputOccupant occupant = examineOutput(target);
  if (occupant.kind == OutputOccupant::Kind::Other) throw std::runtime_error(refusal(target, occupant));
  if (occupant.kind == OutputOccupant::Kind::Nothing) {
    if (!renameWith(built, target, RENAME_NOREPLACE)) {
      if (fs::exists(fs::symlink_status(target)))
        throw std::runtime_error(target.string() + ": appeared while the job was being written; it was left as it is");
      renameOrThrow(built, target);
    }
    return c;
  }
  if (!force)
    throw std::runtime_error(target.string() + ": a job appeared there while this one was being written; use --force to replace it");
  c.replaced = true;
  c.exchanged = renameWith(built, target, RENAME_EXCHANGE);
  if (c.exchanged) {
    c.oldJob = built;
    // The exchange took whatever was at the target a moment ago: it must be the job examined above (the
    // same entry: its files were read there, and a second reading would double the cost).
    struct stat taken {};
    if (::lstat(c.oldJob.c_str(), &taken) != 0 || static_cast<std::uint64_t>(taken.st_dev) != occupant.device ||
        static_cast<std::uint64_t>(taken.st_ino) != occupant.inode) {
      renameWith(c.oldJob, target, RENAME_EXCHANGE);
      throw std::runtime_error(target.string() + ": changed while the job was being written; nothing was replaced");
    }
    return c;
  }
  // No exchange on this file system: the old job is moved aside into the staging folder first.
  c.oldJob = staging.root() / "replaced";
  renameOrThrow(target, c.oldJob);
  try {
    renameOrThrow(built, target);
  } catch (...) {
    renameOrThrow(c.oldJob, target);
    throw;
  }
  return c;
}

void undoCommit(const Commit& c, const fs::path& target, const Staging& staging) {
  if (c.exchanged && renameWith(c.oldJob, target, RENAME_EXCHANGE)) return;  // new job back into staging
  renameOrThrow(target, staging.root() / "withdrawn");
  if (c.replaced) renameOrThrow(c.oldJob, target);
}


}  // namespace rodfab::printer_profiles
