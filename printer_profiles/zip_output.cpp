#include "printer_profiles/zip_output.hpp"

#include "printer_profiles/zip_source_adapter.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;

namespace {

// Written out when the buffered tail reaches this size: small enough to stay in a core's L2 cache
// between libzip's copy into it and the kernel's copy out (8 MiB went through memory both ways: the
// lattice's zip took 0.10-0.25 s to build, 0.045-0.056 s with 512 KiB; printer_profiles/README.md,
// "Emit, round 14"), large enough that its writes are few (260 for the lattice's 132 MB).
constexpr std::size_t kTailBytes = std::size_t{512} << 10;

class ArchiveOutput : public ZipSourceState {
public:
  static constexpr std::array kCommands{ZIP_SOURCE_OPEN,         ZIP_SOURCE_READ,          ZIP_SOURCE_CLOSE,
                                        ZIP_SOURCE_SEEK,         ZIP_SOURCE_TELL,          ZIP_SOURCE_STAT,
                                        ZIP_SOURCE_BEGIN_WRITE,  ZIP_SOURCE_WRITE,         ZIP_SOURCE_SEEK_WRITE,
                                        ZIP_SOURCE_TELL_WRITE,   ZIP_SOURCE_COMMIT_WRITE,  ZIP_SOURCE_ROLLBACK_WRITE,
                                        ZIP_SOURCE_REMOVE};

  explicit ArchiveOutput(fs::path path) : path_(std::move(path)), part_(path_.string() + ".part") {}
  ~ArchiveOutput() { rollbackWrite(); }

  // zip_open_from_source requires the reading commands of any archive's source; a new archive
  // (ZIP_CREATE | ZIP_EXCL) is never read, so they fail.
  zip_int64_t open() { return neverRead(); }
  zip_int64_t read(void*, zip_uint64_t) { return neverRead(); }
  zip_int64_t close() { return neverRead(); }
  zip_int64_t seek(void*, zip_uint64_t) { return neverRead(); }
  zip_int64_t tell() { return neverRead(); }

  // "Does not exist" is ZIP_ER_READ with ENOENT, as libzip's file source says it.
  zip_int64_t stat(zip_stat_t* st) {
    struct stat info {};
    if (::lstat(path_.c_str(), &info) != 0) return failed(ZIP_ER_READ, errno);
    zip_stat_init(st);
    st->size = static_cast<zip_uint64_t>(info.st_size);
    st->valid = ZIP_STAT_SIZE;
    return 0;
  }

  zip_int64_t beginWrite() {
    // 0666 less the umask, as libzip's file source creates archives.
    fd_ = ::open(part_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd_ < 0) return failed(ZIP_ER_TMPOPEN, errno);
    position_ = end_ = tailStart_ = 0;
    tail_.clear();
    tail_.reserve(kTailBytes);
    return 0;
  }

  // Into the buffered tail when the write starts inside it or right after it (local headers are
  // rewritten there once their entry's data is known); anywhere else, the tail is written out first.
  zip_int64_t write(const void* bytes, zip_uint64_t length) {
    const auto* data = static_cast<const std::uint8_t*>(bytes);
    if (position_ < tailStart_ || position_ > tailStart_ + tail_.size()) {
      if (!flush()) return -1;
      tailStart_ = position_;
    }
    const auto at = static_cast<std::size_t>(position_ - tailStart_);
    const std::size_t over = std::min<std::size_t>(length, tail_.size() - at);
    std::memcpy(tail_.data() + at, data, over);
    tail_.insert(tail_.end(), data + over, data + length);
    position_ += length;
    end_ = std::max(end_, position_);
    if (tail_.size() >= kTailBytes && !flush()) return -1;
    return static_cast<zip_int64_t>(length);
  }

  zip_int64_t seekWrite(void* data, zip_uint64_t length) { return seekWithin(position_, end_, data, length); }
  zip_int64_t tellWrite() const { return static_cast<zip_int64_t>(position_); }

  zip_int64_t commitWrite() {
    if (!flush()) return -1;
    const int fd = std::exchange(fd_, -1);
    if (::close(fd) != 0) {
      const int why = errno;
      ::unlink(part_.c_str());
      return failed(ZIP_ER_WRITE, why);
    }
    if (::rename(part_.c_str(), path_.c_str()) != 0) {
      const int why = errno;
      ::unlink(part_.c_str());
      return failed(ZIP_ER_RENAME, why);
    }
    return 0;
  }

  zip_int64_t rollbackWrite() {
    if (fd_ < 0) return 0;
    ::close(std::exchange(fd_, -1));
    ::unlink(part_.c_str());
    return 0;
  }

  zip_int64_t remove() { return ::unlink(path_.c_str()) == 0 || errno == ENOENT ? 0 : failed(ZIP_ER_REMOVE, errno); }

private:
  zip_int64_t neverRead() { return failed(ZIP_ER_OPNOTSUPP, 0); }

  bool flush() {
    std::size_t done = 0;
    while (done < tail_.size()) {
      const ssize_t n = ::pwrite(fd_, tail_.data() + done, tail_.size() - done, static_cast<off_t>(tailStart_ + done));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        failed(ZIP_ER_WRITE, n < 0 ? errno : ENOSPC);
        return false;
      }
      done += static_cast<std::size_t>(n);
    }
    tailStart_ += tail_.size();
    tail_.clear();
    return true;
  }

  fs::path path_, part_;
  int fd_ = -1;
  zip_uint64_t position_ = 0, end_ = 0;
  zip_uint64_t tailStart_ = 0;  // where tail_ goes in the file
  std::vector<std::uint8_t> tail_;
};

}  // namespace

zip_source_t* newArchiveSource(const fs::path& path, zip_error_t* error) {
  return makeZipSource(std::make_unique<ArchiveOutput>(path), error);
}

}  // namespace rodfab::printer_profiles
