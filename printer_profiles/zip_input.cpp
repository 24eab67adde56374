#include "printer_profiles/zip_input.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <vector>

namespace rodfab::printer_profiles {

namespace {

constexpr std::size_t kReadAhead = std::size_t{1} << 20;

class FileInput {
public:
  explicit FileInput(int fd) : fd_(fd) {
    zip_error_init(&error_);
    struct stat info {};
    if (::fstat(fd_, &info) != 0) statErrno_ = errno;
    size_ = static_cast<zip_uint64_t>(info.st_size);
    mtime_ = info.st_mtime;
  }
  ~FileInput() {
    ::close(fd_);
    zip_error_fini(&error_);
  }
  FileInput(const FileInput&) = delete;
  FileInput& operator=(const FileInput&) = delete;

  static zip_int64_t callback(void* self, void* data, zip_uint64_t length, zip_source_cmd_t command) {
    auto* input = static_cast<FileInput*>(self);
    if (command == ZIP_SOURCE_FREE) {
      delete input;
      return 0;
    }
    return input->handle(data, length, command);
  }

private:
  zip_int64_t handle(void* data, zip_uint64_t length, zip_source_cmd_t command) {
    switch (command) {
      case ZIP_SOURCE_OPEN: position_ = 0; return 0;
      case ZIP_SOURCE_READ: return read(static_cast<std::uint8_t*>(data), length);
      case ZIP_SOURCE_CLOSE: return 0;
      case ZIP_SOURCE_SEEK: {
        const zip_int64_t to = zip_source_seek_compute_offset(position_, size_, data, length, &error_);
        if (to < 0) return -1;
        position_ = static_cast<zip_uint64_t>(to);
        return 0;
      }
      case ZIP_SOURCE_TELL: return static_cast<zip_int64_t>(position_);
      case ZIP_SOURCE_STAT: return stat(static_cast<zip_stat_t*>(data));
      case ZIP_SOURCE_ERROR: return zip_error_to_data(&error_, data, length);
      case ZIP_SOURCE_SUPPORTS:
        return zip_source_make_command_bitmap(ZIP_SOURCE_OPEN, ZIP_SOURCE_READ, ZIP_SOURCE_CLOSE, ZIP_SOURCE_SEEK, ZIP_SOURCE_TELL,
                                              ZIP_SOURCE_STAT, ZIP_SOURCE_ERROR, ZIP_SOURCE_FREE, -1);
      default: return failed(ZIP_ER_OPNOTSUPP, 0);
    }
  }

  zip_int64_t failed(int code, int systemError) {
    zip_error_set(&error_, code, systemError);
    return -1;
  }

  zip_int64_t stat(zip_stat_t* st) {
    if (statErrno_) return failed(ZIP_ER_READ, statErrno_);
    zip_stat_init(st);
    st->size = size_;
    st->mtime = mtime_;
    st->valid = ZIP_STAT_SIZE | ZIP_STAT_MTIME;
    return 0;
  }

  // Up to `length` bytes from the position, fewer only at the end of the file.
  zip_int64_t read(std::uint8_t* out, zip_uint64_t length) {
    zip_uint64_t done = 0;
    while (done < length && position_ < size_) {
      if (position_ < aheadStart_ || position_ >= aheadStart_ + ahead_.size()) {
        if (!fill()) return failed(ZIP_ER_READ, errno);
        if (ahead_.empty()) break;  // shorter than it was: libzip reports the entry as truncated
      }
      const auto at = static_cast<std::size_t>(position_ - aheadStart_);
      const std::size_t n = static_cast<std::size_t>(std::min<zip_uint64_t>(length - done, ahead_.size() - at));
      std::memcpy(out + done, ahead_.data() + at, n);
      done += n;
      position_ += n;
    }
    return static_cast<zip_int64_t>(done);
  }

  bool fill() {
    ahead_.resize(kReadAhead);
    std::size_t got = 0;
    for (;;) {
      const ssize_t n = ::pread(fd_, ahead_.data() + got, kReadAhead - got, static_cast<off_t>(position_ + got));
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        ahead_.clear();
        return false;
      }
      got += static_cast<std::size_t>(n);
      if (n == 0 || got == kReadAhead) break;
    }
    ahead_.resize(got);
    aheadStart_ = position_;
    return true;
  }

  int fd_;
  zip_error_t error_;
  int statErrno_ = 0;
  zip_uint64_t size_ = 0;
  time_t mtime_ = 0;
  zip_uint64_t position_ = 0;
  zip_uint64_t aheadStart_ = 0;  // the file's bytes [aheadStart_, aheadStart_ + ahead_.size()) are in ahead_
  std::vector<std::uint8_t> ahead_;
};

}  // namespace

zip_source_t* newFileReadSource(int fd, zip_error_t* error) {
  auto* input = new FileInput(fd);
  zip_source_t* source = zip_source_function_create(FileInput::callback, input, error);
  if (!source) delete input;  // closes fd
  return source;
}

}  // namespace rodfab::printer_profiles
