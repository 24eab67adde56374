#include "printer_profiles/zip_input.hpp"

#include "printer_profiles/zip_source_adapter.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

namespace rodfab::printer_profiles {

namespace {

// A read anywhere but where the last read-ahead ended fetches a page; reading on from there fetches
// twice as much as the last time, from 64 KiB up to 1 MiB (an entry streamed, the entries one after
// another, the central directory). libzip opening an archive with ZIP_CHECKCONS reads every entry's
// local header, one after another across the file, and the job reader's threads share its handles, so a
// handle's next entry is often far from its last one: with 1 MiB for every such read, opening the
// lattice's job read all of its 132 MB, each handle again, and `rodfab inspect` read 417 MB of it in
// all (bench/README.md, "Emit, round 11").
constexpr std::size_t kProbe = std::size_t{4} << 10;
constexpr std::size_t kFirstRun = std::size_t{64} << 10;
constexpr std::size_t kReadAhead = std::size_t{1} << 20;

class FileInput : public ZipSourceState {
public:
  static constexpr std::array kCommands{ZIP_SOURCE_OPEN, ZIP_SOURCE_READ, ZIP_SOURCE_CLOSE,
                                        ZIP_SOURCE_SEEK, ZIP_SOURCE_TELL, ZIP_SOURCE_STAT};

  explicit FileInput(int fd) : fd_(fd) {
    struct stat info {};
    if (::fstat(fd_, &info) != 0) statErrno_ = errno;
    size_ = static_cast<zip_uint64_t>(info.st_size);
    mtime_ = info.st_mtime;
  }
  ~FileInput() { ::close(fd_); }

  zip_int64_t open() {
    position_ = 0;
    return 0;
  }
  zip_int64_t read(void* data, zip_uint64_t length) { return readAt(static_cast<std::uint8_t*>(data), length); }
  zip_int64_t close() { return 0; }
  zip_int64_t seek(void* data, zip_uint64_t length) { return seekWithin(position_, size_, data, length); }
  zip_int64_t tell() const { return static_cast<zip_int64_t>(position_); }

  zip_int64_t stat(zip_stat_t* st) {
    if (statErrno_) return failed(ZIP_ER_READ, statErrno_);
    zip_stat_init(st);
    st->size = size_;
    st->mtime = mtime_;
    st->valid = ZIP_STAT_SIZE | ZIP_STAT_MTIME;
    return 0;
  }

private:
  // Up to `length` bytes from the position, fewer only at the end of the file.
  zip_int64_t readAt(std::uint8_t* out, zip_uint64_t length) {
    zip_uint64_t done = 0;
    while (done < length && position_ < size_) {
      if (position_ < aheadStart_ || position_ >= aheadStart_ + aheadBytes_) {
        if (!fill()) return failed(ZIP_ER_READ, errno);
        if (aheadBytes_ == 0) break;  // shorter than it was: libzip reports the entry as truncated
      }
      const auto at = static_cast<std::size_t>(position_ - aheadStart_);
      const std::size_t n = static_cast<std::size_t>(std::min<zip_uint64_t>(length - done, aheadBytes_ - at));
      std::memcpy(out + done, ahead_.data() + at, n);
      done += n;
      position_ += n;
    }
    return static_cast<zip_int64_t>(done);
  }

  bool fill() {
    const bool onward = aheadBytes_ != 0 && position_ == aheadStart_ + aheadBytes_;
    const std::size_t want = onward ? std::clamp(2 * aheadBytes_, kFirstRun, kReadAhead) : kProbe;
    if (ahead_.empty()) ahead_.resize(kReadAhead);  // once: the reads keep its bytes between them
    aheadBytes_ = 0;
    std::size_t got = 0;
    for (;;) {
      const ssize_t n = ::pread(fd_, ahead_.data() + got, want - got, static_cast<off_t>(position_ + got));
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) return false;
      got += static_cast<std::size_t>(n);
      if (n == 0 || got == want) break;
    }
    aheadBytes_ = got;
    aheadStart_ = position_;
    return true;
  }

  int fd_;
  int statErrno_ = 0;
  zip_uint64_t size_ = 0;
  time_t mtime_ = 0;
  zip_uint64_t position_ = 0;
  zip_uint64_t aheadStart_ = 0;  // the file's bytes [aheadStart_, aheadStart_ + aheadBytes_) are in ahead_
  std::size_t aheadBytes_ = 0;
  std::vector<std::uint8_t> ahead_;
};

}  // namespace

zip_source_t* newFileReadSource(int fd, zip_error_t* error) {
  return makeZipSource(std::make_unique<FileInput>(fd), error);  // closes fd when it fails
}

}  // namespace rodfab::printer_profiles
