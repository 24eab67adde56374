#include "printer_profiles/job_reader.hpp"

#include "printer_profiles/deflate.hpp"
#include "printer_profiles/zip_input.hpp"
#include "printer_profiles/zip_layout_check.hpp"
#include "printer_profiles/zip_pool.hpp"

#include <zip.h>

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <optional>
#include <utility>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kChunk = 64 * 1024;

// A chunk's buffer, not cleared: every byte read from it was written by the read first. Cleared (a
// std::vector), it was 64 KiB of memset for every entry read: 393 M of the lattice writer's 16.6 G
// instructions, its verification reading 6,000 entries (bench/README.md, "Emit, round 11").
std::unique_ptr<std::uint8_t[]> chunkBuffer() { return std::make_unique_for_overwrite<std::uint8_t[]>(kChunk); }

std::string errnoText() { return std::strerror(errno); }

// What a file type other than a regular file or folder is, for messages.
std::string describeMode(mode_t mode) {
  switch (mode & S_IFMT) {
    case S_IFLNK: return "a symbolic link";
    case S_IFIFO: return "a FIFO (named pipe)";
    case S_IFCHR: return "a character device";
    case S_IFBLK: return "a block device";
    case S_IFSOCK: return "a socket";
    case S_IFDIR: return "a folder";
    case S_IFREG: return "a regular file";
  }
  return "a special file";
}

// Closes a file descriptor when it goes out of scope.
struct Fd {
  int fd = -1;
  explicit Fd(int f) : fd(f) {}
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int release() { return std::exchange(fd, -1); }
};

// Reads `fd` (a regular file) to its end in chunks, refusing more than maxBytes.
void streamFd(int fd, const std::string& where, std::uint64_t maxBytes,
              const std::function<void(std::span<const std::uint8_t>)>& sink) {
  const auto buffer = chunkBuffer();
  std::uint64_t total = 0;
  for (;;) {
    const ssize_t got = ::read(fd, buffer.get(), kChunk);
    if (got < 0) {
      if (errno == EINTR) continue;
      throw JobReadError(where + ": cannot be read (" + errnoText() + ")");
    }
    if (got == 0) return;
    total += static_cast<std::uint64_t>(got);
    if (total > maxBytes)
      throw EntryTooLarge(where + ": holds more than " + std::to_string(maxBytes) + " bytes, the most it can take", maxBytes);
    sink(std::span<const std::uint8_t>(buffer.get(), static_cast<std::size_t>(got)));
  }
}

// ------------------------------------------------------------------------------------------ folders

class DirectoryJobReader final : public JobReader {
public:
  DirectoryJobReader(fs::path root, int rootFd, std::size_t maxEntries, int maxDepth)
      : JobReader(std::move(root), ArchiveFormat::Directory, maxEntries), maxDepth_(maxDepth) {
    dirs_.push_back(rootFd);
    try {
      walk(0, "", 1);
    } catch (...) {
      for (int fd : dirs_) ::close(fd);  // the destructor does not run for a throwing constructor
      throw;
    }
  }
  ~DirectoryJobReader() override {
    for (int fd : dirs_) ::close(fd);
  }
  void stream(const JobEntry& entry, std::uint64_t maxBytes,
              const std::function<void(std::span<const std::uint8_t>)>& sink) const override {
    const Found& f = found_.at(entry.index);
    const std::string where = path().string() + ": " + printableName(entry.name);
    // O_NOFOLLOW: a link put in place since the listing is refused; O_NONBLOCK: so is a FIFO, at once.
    Fd fd(::openat(dirs_[f.dir], f.leaf.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC | O_NOCTTY));
    if (fd.fd < 0) throw JobReadError(where + ": cannot be opened (" + errnoText() + ")");
    struct stat st{};
    if (::fstat(fd.fd, &st) != 0) throw JobReadError(where + ": cannot be examined (" + errnoText() + ")");
    if (!S_ISREG(st.st_mode) || st.st_dev != f.dev || st.st_ino != f.ino)
      throw JobReadError(where + ": was replaced by " + describeMode(st.st_mode) + " while the job was being inspected");
    streamFd(fd.fd, where, maxBytes, sink);
  }
  std::optional<JobEntry> findUnlisted(const std::string& name) override {
    struct stat st{};
    if (name.empty() || name.find('/') != std::string::npos || ::fstatat(dirs_[0], name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0)
      return std::nullopt;
    return entryFor(0, name, "", st);
  }

private:
  struct Found {
    std::size_t dir = 0;  // index in dirs_
    std::string leaf;
    dev_t dev = 0;
    ino_t ino = 0;
  };

  std::vector<std::string> sortedNames(int dirFd) {
    Fd copy(::dup(dirFd));
    DIR* d = copy.fd >= 0 ? ::fdopendir(copy.fd) : nullptr;
    if (!d) throw JobReadError(path().string() + ": cannot list the folder (" + errnoText() + ")");
    copy.release();
    std::vector<std::string> names;
    while (const dirent* e = ::readdir(d)) {
      const std::string name = e->d_name;
      if (name == "." || name == "..") continue;
      if (names.size() > maxEntries()) break;  // enough to know there are too many
      names.push_back(name);
    }
    ::closedir(d);
    std::sort(names.begin(), names.end());
    return names;
  }

  void add(JobEntry entry) {
    if (roomForEntry()) addEntry(std::move(entry));
  }

  // The entry `leaf` of folder dirs_[dir] (named prefix + leaf in the job) as fstatat found it; a
  // regular file is remembered for reading.
  JobEntry entryFor(std::size_t dir, const std::string& leaf, const std::string& prefix, const struct stat& st) {
    JobEntry entry{prefix + leaf, EntryKind::Other, static_cast<std::uint64_t>(st.st_size), describeMode(st.st_mode), 0};
    if (S_ISREG(st.st_mode)) {
      entry.kind = EntryKind::File;
      entry.index = found_.size();
      found_.push_back({dir, leaf, st.st_dev, st.st_ino});
    } else if (S_ISDIR(st.st_mode)) {
      entry.kind = EntryKind::Directory;
      entry.name += '/';
      entry.declaredBytes = 0;
    }
    return entry;
  }

  void walk(std::size_t dir, const std::string& prefix, int depth) {
    for (const std::string& leaf : sortedNames(dirs_[dir])) {
      if (truncated()) return;
      struct stat st{};
      if (::fstatat(dirs_[dir], leaf.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0)
        throw JobReadError(path().string() + ": " + printableName(prefix + leaf) + ": cannot be examined (" + errnoText() + ")");
      JobEntry entry = entryFor(dir, leaf, prefix, st);  // anything but a file or folder is never opened
      const bool folder = entry.kind == EntryKind::Directory;
      add(std::move(entry));
      if (folder && depth < maxDepth_) descend(dir, leaf, prefix + leaf + "/", depth + 1);
    }
  }

  void descend(std::size_t dir, const std::string& leaf, const std::string& prefix, int depth) {
    const int fd = ::openat(dirs_[dir], leaf.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (fd < 0) throw JobReadError(path().string() + ": " + printableName(prefix) + ": cannot be opened (" + errnoText() + ")");
    dirs_.push_back(fd);
    walk(dirs_.size() - 1, prefix, depth);
  }

  int maxDepth_;
  std::vector<int> dirs_;
  std::vector<Found> found_;
};

// ------------------------------------------------------------------------------------------ zip

std::string zipErrorText(int code) {
  zip_error_t ze;
  zip_error_init_with_code(&ze, code);
  std::string why = zip_error_strerror(&ze);
  zip_error_fini(&ze);
  return why;
}

// libzip handles are not thread-safe: readers borrow one from a pool (zip_pool.hpp). Every handle is
// opened from a descriptor checked to be the same regular file the first one was, unchanged (size and
// modification time). The first open checks every local header against the central directory
// (ZIP_CHECKCONS, which reads each entry's header: 6,000 reads on the lattice's job); the others open
// the same bytes without repeating it (printer_profiles/README.md, "Emit, round 14").
class ZipJobReader final : public JobReader {
public:
  ZipJobReader(fs::path file, int fd, const struct stat& st, std::size_t maxEntries)
      : JobReader(std::move(file), ArchiveFormat::Zip, maxEntries), dev_(st.st_dev), ino_(st.st_ino), size_(st.st_size),
        mtime_(st.st_mtim), pool_([this] { return reopen(); }) {
    const Fd copy(::fcntl(fd, F_DUPFD_CLOEXEC, 0));  // adopt takes fd
    zip_t* za = adopt(fd, ZIP_CHECKCONS);
    pool_.giveBack(za);
    if (copy.fd < 0) throw JobReadError(path().string() + ": cannot be read (" + errnoText() + ")");
    checkLocalEntriesTile(copy.fd, static_cast<std::uint64_t>(size_), za, path().string());
    list(za);
  }
  void stream(const JobEntry& entry, std::uint64_t maxBytes,
              const std::function<void(std::span<const std::uint8_t>)>& sink) const override {
    const ZipPool::Lease za(pool_);
    streamEntry(za.get(), entry, maxBytes, sink);
  }

  StoredEntryInfo streamStored(const JobEntry& entry, std::uint64_t maxBytes,
                               const std::function<void(std::span<const std::uint8_t>)>& sink) const override {
    const ZipPool::Lease za(pool_);
    const std::string where = path().string() + ": " + printableName(entry.name);
    zip_stat_t st;
    zip_stat_init(&st);
    constexpr zip_uint64_t kNeeded = ZIP_STAT_COMP_METHOD | ZIP_STAT_CRC | ZIP_STAT_SIZE;
    if (zip_stat_index(za.get(), entry.index, 0, &st) != 0 || (st.valid & kNeeded) != kNeeded ||
        (st.comp_method != ZIP_CM_DEFLATE && st.comp_method != ZIP_CM_STORE))
      throw JobReadError(where + ": is neither stored nor deflated, or its zip directory record cannot be read");
    std::uint64_t total = 0;
    forEachChunk(za.get(), entry, ZIP_FL_COMPRESSED, where, [&](std::span<const std::uint8_t> raw) {
      total += raw.size();
      if (total > maxBytes)
        throw EntryTooLarge(where + ": holds more than " + std::to_string(maxBytes) + " stored bytes, the most it can take", maxBytes);
      sink(raw);
    });
    return {st.comp_method == ZIP_CM_DEFLATE, st.size, st.crc};
  }

  std::optional<JobEntry> findUnlisted(const std::string& name) override {
    if (name.empty() || name.find('/') != std::string::npos) return std::nullopt;
    const ZipPool::Lease za(pool_);
    const zip_int64_t index = zip_name_locate(za.get(), name.c_str(), ZIP_FL_ENC_RAW);
    if (index < 0) return std::nullopt;
    return entryAt(za.get(), static_cast<zip_uint64_t>(index));
  }

private:
  // Through a read-ahead source (zip_input.hpp), which owns fd from here.
  zip_t* adopt(int fd, int checks) const {
    zip_error_t ze;
    zip_error_init(&ze);
    zip_source_t* source = newFileReadSource(fd, &ze);
    zip_t* za = source ? zip_open_from_source(source, ZIP_RDONLY | checks, &ze) : nullptr;
    const int error = zip_error_code_zip(&ze);
    zip_error_fini(&ze);
    if (!za) {
      if (source) zip_source_free(source);
      if (error == ZIP_ER_EXISTS)  // libzip refuses a central directory naming one entry twice
        throw JobReadError(path().string() + ": holds two entries of the same name (unpacking would keep only one)");
      throw JobReadError(path().string() + ": not a readable zip archive (" + zipErrorText(error) +
                         "); it may be truncated or damaged");
    }
    return za;
  }

  void list(zip_t* za) {
    const zip_int64_t count = zip_get_num_entries(za, 0);
    for (zip_int64_t n = 0; n < count && roomForEntry(); ++n) addEntry(entryAt(za, static_cast<zip_uint64_t>(n)));
  }

  JobEntry entryAt(zip_t* za, zip_uint64_t index) const {
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(za, index, ZIP_FL_ENC_RAW, &st) != 0 || !(st.valid & ZIP_STAT_NAME))
      throw JobReadError(path().string() + ": entry " + std::to_string(index) + " of the archive cannot be read (" +
                         zip_strerror(za) + ")");
    JobEntry entry{st.name, EntryKind::File, (st.valid & ZIP_STAT_SIZE) ? st.size : 0, "", index};
    if (!entry.name.empty() && entry.name.back() == '/') entry.kind = EntryKind::Directory;
    classify(za, st, entry);
    return entry;
  }

  // Marks entries no job holds: links and devices (by their Unix mode), encryption, other compressions.
  static void classify(zip_t* za, const zip_stat_t& st, JobEntry& entry) {
    zip_uint8_t opsys = 0;
    zip_uint32_t attributes = 0;
    if (zip_file_get_external_attributes(za, entry.index, 0, &opsys, &attributes) == 0 && opsys == ZIP_OPSYS_UNIX) {
      const auto mode = static_cast<mode_t>(attributes >> 16);
      const mode_t type = mode & S_IFMT;
      if (type != 0 && type != S_IFREG && type != S_IFDIR) {
        entry.kind = EntryKind::Other;
        entry.otherWhat = describeMode(mode) + " (Unix mode in the archive)";
        return;
      }
    }
    if (entry.kind != EntryKind::File) return;
    if ((st.valid & ZIP_STAT_ENCRYPTION_METHOD) && st.encryption_method != ZIP_EM_NONE) {
      entry.kind = EntryKind::Other;
      entry.otherWhat = "an encrypted entry";
    } else if ((st.valid & ZIP_STAT_COMP_METHOD) && st.comp_method != ZIP_CM_STORE && st.comp_method != ZIP_CM_DEFLATE) {
      entry.kind = EntryKind::Other;
      entry.otherWhat = "an entry compressed with method " + std::to_string(st.comp_method) + " (a job stores or deflates)";
    }
  }

  void streamEntry(zip_t* za, const JobEntry& entry, std::uint64_t maxBytes,
                   const std::function<void(std::span<const std::uint8_t>)>& sink) const {
    const std::string where = path().string() + ": " + printableName(entry.name);
    if (entry.declaredBytes > maxBytes)
      throw EntryTooLarge(where + ": its zip header declares " + std::to_string(entry.declaredBytes) +
                              " bytes, more than the " + std::to_string(maxBytes) + " it can take",
                          maxBytes);
    zip_stat_t st;
    zip_stat_init(&st);
    constexpr zip_uint64_t kPlain = ZIP_STAT_COMP_METHOD | ZIP_STAT_CRC;
    const bool plain = zip_stat_index(za, entry.index, 0, &st) == 0 && (st.valid & kPlain) == kPlain &&
                       (!(st.valid & ZIP_STAT_ENCRYPTION_METHOD) || st.encryption_method == ZIP_EM_NONE) &&
                       (st.comp_method == ZIP_CM_DEFLATE || st.comp_method == ZIP_CM_STORE);
    std::uint64_t total = 0;
    const auto counted = [&](std::span<const std::uint8_t> piece) {
      total += piece.size();
      if (total > maxBytes)
        throw EntryTooLarge(where + ": expands to more than " + std::to_string(maxBytes) + " bytes, the most it can take", maxBytes);
      sink(piece);
    };
    if (plain) streamPlain(za, entry, st, where, counted);
    else forEachChunk(za, entry, 0, where, counted);  // libzip decodes, checking the CRC at the end, or says why not
    // A stored entry is read by its compressed size: a different declared size is a damaged header
    // (0 is what an archive without sizes reports).
    if (entry.declaredBytes != 0 && total != entry.declaredBytes)
      throw JobReadError(where + ": is damaged (its zip header declares " + std::to_string(entry.declaredBytes) +
                         " bytes, it holds " + std::to_string(total) + ")");
  }

  // Stored or deflated entries: the raw bytes through libzip, inflated and CRC-checked by igzip
  // (deflate.hpp), several times faster than libzip's zlib path (verification reads every image).
  void streamPlain(zip_t* za, const JobEntry& entry, const zip_stat_t& st, const std::string& where,
                   const std::function<void(std::span<const std::uint8_t>)>& sink) const {
    const bool stored = st.comp_method == ZIP_CM_STORE;
    std::uint32_t crc = 0;
    std::optional<InflateStream> inflater;
    if (!stored) inflater.emplace();
    InflateStream::Status status = InflateStream::Status::More;
    forEachChunk(za, entry, ZIP_FL_COMPRESSED, where, [&](std::span<const std::uint8_t> raw) {
      if (stored) {
        crc = zipCrc32(raw, crc);
        sink(raw);
      } else if (status == InflateStream::Status::More) {
        status = inflater->add(raw, sink);
        if (status == InflateStream::Status::Damaged) throw JobReadError(where + ": is damaged (invalid deflate data)");
      }
    });
    if (!stored && status != InflateStream::Status::End) throw JobReadError(where + ": is damaged (the deflate data ends early)");
    if ((stored ? crc : inflater->crc()) != st.crc) throw JobReadError(where + ": is damaged (CRC error)");
  }

  // The entry's bytes in chunks: as the archive holds them with ZIP_FL_COMPRESSED, decoded without.
  void forEachChunk(zip_t* za, const JobEntry& entry, zip_flags_t flags, const std::string& where,
                    const std::function<void(std::span<const std::uint8_t>)>& use) const {
    zip_file_t* zf = zip_fopen_index(za, entry.index, flags);
    if (!zf) throw JobReadError(where + ": cannot be opened (" + zip_strerror(za) + ")");
    const auto buffer = chunkBuffer();
    try {
      for (;;) {
        const zip_int64_t got = zip_fread(zf, buffer.get(), kChunk);
        if (got < 0) throw JobReadError(where + ": is damaged (" + zip_file_strerror(zf) + ")");
        if (got == 0) break;
        use(std::span<const std::uint8_t>(buffer.get(), static_cast<std::size_t>(got)));
      }
    } catch (...) {
      zip_fclose(zf);
      throw;
    }
    zip_fclose(zf);
  }

  // Another handle, from a descriptor checked to be the same regular file the first one was.
  zip_t* reopen() const {
    Fd fd(::open(path().c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY));
    struct stat st{};
    if (fd.fd < 0 || ::fstat(fd.fd, &st) != 0) throw JobReadError(path().string() + ": cannot be reopened (" + errnoText() + ")");
    if (!S_ISREG(st.st_mode) || st.st_dev != dev_ || st.st_ino != ino_)
      throw JobReadError(path().string() + ": was replaced while the job was being inspected");
    if (st.st_size != size_ || st.st_mtim.tv_sec != mtime_.tv_sec || st.st_mtim.tv_nsec != mtime_.tv_nsec)
      throw JobReadError(path().string() + ": was changed while the job was being inspected");
    return adopt(fd.release(), 0);
  }

  dev_t dev_;
  ino_t ino_;
  off_t size_;
  timespec mtime_;
  ZipPool pool_;
};

bool isWindowsDeviceName(std::string_view component) {
  std::string stem(component.substr(0, component.find('.')));
  for (char& c : stem) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  static constexpr std::array<std::string_view, 4> kPlain = {"CON", "PRN", "AUX", "NUL"};
  if (std::find(kPlain.begin(), kPlain.end(), stem) != kPlain.end()) return true;
  return stem.size() == 4 && (stem.starts_with("COM") || stem.starts_with("LPT")) && std::isdigit(static_cast<unsigned char>(stem[3]));
}

std::optional<std::string> unsafeComponent(std::string_view c) {
  if (c.empty()) return "has an empty path component ('//')";
  if (c == "." || c == "..") return "has a '" + std::string(c) + "' component: it could point outside the job";
  if (c.size() > 255) return "has a component longer than 255 bytes";
  if (c.back() == '.' || c.back() == ' ') return "has a component ending in a dot or a space (Windows drops them)";
  if (isWindowsDeviceName(c)) return "names a Windows device (" + std::string(c) + ")";
  return std::nullopt;
}

}  // namespace

StoredEntryInfo JobReader::streamStored(const JobEntry& entry, std::uint64_t,
                                        const std::function<void(std::span<const std::uint8_t>)>&) const {
  throw JobReadError(path().string() + ": " + printableName(entry.name) + ": a folder job's file has no stored form to read");
}

Bytes JobReader::read(const JobEntry& entry, std::uint64_t maxBytes) const {
  Bytes data;
  data.reserve(static_cast<std::size_t>(std::min<std::uint64_t>({entry.declaredBytes, maxBytes, 64u << 20})));
  stream(entry, maxBytes, [&](std::span<const std::uint8_t> chunk) { data.insert(data.end(), chunk.begin(), chunk.end()); });
  return data;
}

std::unique_ptr<JobReader> openJobReader(const fs::path& job, std::size_t maxEntries, int maxDepth) {
  // O_NONBLOCK: opening a FIFO returns at once instead of waiting for a writer.
  const int fd = ::open(job.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    if (errno == ENOENT) throw JobReadError(job.string() + ": no such job (expected a .zip archive or a folder)");
    throw JobReadError(job.string() + ": cannot be opened (" + errnoText() + ")");
  }
  struct stat st{};
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    throw JobReadError(job.string() + ": cannot be examined (" + errnoText() + ")");
  }
  if (S_ISDIR(st.st_mode)) return std::make_unique<DirectoryJobReader>(job, fd, maxEntries, maxDepth);
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw JobReadError(job.string() + ": is " + describeMode(st.st_mode) + ", not a job (a .zip archive or a folder)");
  }
  return std::make_unique<ZipJobReader>(job, fd, st, maxEntries);
}

std::optional<std::string> unsafeEntryName(std::string_view name) {
  if (name.empty()) return "is empty";
  if (name.size() > 1024) return "is longer than 1024 bytes";
  for (const char ch : name) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c == 0x7f) return "holds a control character";
    if (c >= 0x80) return "holds a byte that is not printable ASCII";
    if (c == '\\') return "holds a backslash (a folder separator on Windows)";
    if (c == ':') return "holds a ':' (a drive letter or stream name on Windows)";
    if (std::strchr("<>\"|?*", ch)) return std::string("holds '") + ch + "', which Windows refuses in file names";
  }
  if (name.front() == '/') return "is an absolute path";
  std::string_view rest = name;
  if (rest.back() == '/') rest.remove_suffix(1);  // a folder entry
  for (;;) {
    const std::size_t slash = rest.find('/');
    if (auto why = unsafeComponent(rest.substr(0, slash))) return why;
    if (slash == std::string_view::npos) return std::nullopt;
    rest.remove_prefix(slash + 1);
  }
}

std::string printableName(std::string_view name) {
  std::string out;
  for (const char ch : name) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c < 0x7f && c != '\\') {
      out += ch;
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    }
    if (out.size() >= 200) return out + "...";
  }
  return out;
}

}  // namespace rodfab::printer_profiles
