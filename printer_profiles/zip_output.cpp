#include "printer_profiles/zip_output.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;

namespace {

// Written out when the buffered tail reaches this size.
constexpr std::size_t kTailBytes = std::size_t{8} << 20;

class ArchiveOutput {
public:
  explicit ArchiveOutput(fs::path path) : path_(std::move(path)), part_(path_.string() + ".part") { zip_error_init(&error_); }
  ~ArchiveOutput() {
    rollback();
    zip_error_fini(&error_);
  }
  ArchiveOutput(const ArchiveOutput&) = delete;
  ArchiveOutput& operator=(const ArchiveOutput&) = delete;

  static zip_int64_t callback(void* self, void* data, zip_uint64_t length, zip_source_cmd_t command) {
    auto* output = static_cast<ArchiveOutput*>(self);
    if (command == ZIP_SOURCE_FREE) {
      delete output;
      return 0;
    }
    return output->handle(data, length, command);
  }

private:
  zip_int64_t handle(void* data, zip_uint64_t length, zip_source_cmd_t command) {
    switch (command) {
      case ZIP_SOURCE_STAT: return stat(static_cast<zip_stat_t*>(data));
      case ZIP_SOURCE_BEGIN_WRITE: return begin();
      case ZIP_SOURCE_WRITE: return write(static_cast<const std::uint8_t*>(data), length);
      case ZIP_SOURCE_SEEK_WRITE: return seek(data, length);
      case ZIP_SOURCE_TELL_WRITE: return static_cast<zip_int64_t>(position_);
      case ZIP_SOURCE_COMMIT_WRITE: return commit();
      case ZIP_SOURCE_ROLLBACK_WRITE: rollback(); return 0;
      case ZIP_SOURCE_REMOVE: return ::unlink(path_.c_str()) == 0 || errno == ENOENT ? 0 : failed(ZIP_ER_REMOVE, errno);
      case ZIP_SOURCE_ERROR: return zip_error_to_data(&error_, data, length);
      case ZIP_SOURCE_SUPPORTS:
        // The reading commands are listed because zip_open_from_source requires them of any source;
        // a new archive is never read, so they fail.
        return zip_source_make_command_bitmap(ZIP_SOURCE_OPEN, ZIP_SOURCE_READ, ZIP_SOURCE_CLOSE, ZIP_SOURCE_SEEK, ZIP_SOURCE_TELL,
                                              ZIP_SOURCE_STAT, ZIP_SOURCE_ERROR, ZIP_SOURCE_FREE, ZIP_SOURCE_BEGIN_WRITE,
                                              ZIP_SOURCE_WRITE, ZIP_SOURCE_SEEK_WRITE, ZIP_SOURCE_TELL_WRITE,
                                              ZIP_SOURCE_COMMIT_WRITE, ZIP_SOURCE_ROLLBACK_WRITE, ZIP_SOURCE_REMOVE, -1);
      default: return failed(ZIP_ER_OPNOTSUPP, 0);
    }
  }

  zip_int64_t failed(int code, int systemError) {
    zip_error_set(&error_, code, systemError);
    return -1;
  }

  // "Does not exist" is ZIP_ER_READ with ENOENT, as libzip's file source says it.
  zip_int64_t stat(zip_stat_t* st) {
    struct stat info {};
    if (::lstat(path_.c_str(), &info) != 0) return failed(ZIP_ER_READ, errno);
    zip_stat_init(st);
    st->size = static_cast<zip_uint64_t>(info.st_size);
    st->valid = ZIP_STAT_SIZE;
    return 0;
  }

  zip_int64_t begin() {
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
  zip_int64_t write(const std::uint8_t* data, zip_uint64_t length) {
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

  zip_int64_t seek(void* data, zip_uint64_t length) {
    const zip_int64_t to = zip_source_seek_compute_offset(position_, end_, data, length, &error_);
    if (to < 0) return -1;
    position_ = static_cast<zip_uint64_t>(to);
    return 0;
  }

  zip_int64_t commit() {
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

  void rollback() {
    if (fd_ < 0) return;
    ::close(std::exchange(fd_, -1));
    ::unlink(part_.c_str());
  }

  fs::path path_, part_;
  zip_error_t error_;
  int fd_ = -1;
  zip_uint64_t position_ = 0, end_ = 0;
  zip_uint64_t tailStart_ = 0;  // where tail_ goes in the file
  std::vector<std::uint8_t> tail_;
};

}  // namespace

zip_source_t* newArchiveSource(const fs::path& path, zip_error_t* error) {
  auto* output = new ArchiveOutput(path);
  zip_source_t* source = zip_source_function_create(ArchiveOutput::callback, output, error);
  if (!source) delete output;
  return source;
}

}  // namespace rodfab::printer_profiles
