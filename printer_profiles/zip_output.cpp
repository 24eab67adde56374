#include "printer_profiles/zip_output.hpp"

#include "printer_profiles/zip_source_adapter.hpp"

#include <tbb/task_arena.h>

#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;

namespace {

// Written out (by the BlockWriter, while the next tail fills) when the buffered tail reaches this size.
constexpr std::size_t kTailBytes = std::size_t{8} << 20;

// `data` written at `at` of `fd`, however many pwrite calls it takes: 0, or the errno of the failure
// (ENOSPC when the file system takes nothing).
int writeAt(int fd, const std::vector<std::uint8_t>& data, zip_uint64_t at) {
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::pwrite(fd, data.data() + done, data.size() - done, static_cast<off_t>(at + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return n < 0 ? errno : ENOSPC;
    done += static_cast<std::size_t>(n);
  }
  return 0;
}

// Writes the archive's flushed blocks on a thread of its own while libzip fills the next one: the
// kernel's copy of the archive into the page cache (a third of building a lattice job's 132 MB zip)
// runs beside libzip's work instead of after it. Double-buffered: one block in flight, one being
// filled, so at most two blocks are held. Blocks are written in the order they are handed over, so a
// later block over the same bytes (a local header rewritten after its block went) wins, as it did
// written in line. The first failure's errno is kept; the blocks after it are not written.
// The thread takes no signals: SIGINT and SIGTERM go to the threads that poll for them.
class BlockWriter {
public:
  // Throws std::system_error when the thread cannot be started.
  explicit BlockWriter(int fd) : fd_(fd), thread_([this] { run(); }) {}
  // Writes the block in flight, if any, and ends the thread.
  ~BlockWriter() {
    {
      const std::lock_guard lock(mutex_);
      stop_ = true;
    }
    changed_.notify_all();
    thread_.join();
  }
  BlockWriter(const BlockWriter&) = delete;
  BlockWriter& operator=(const BlockWriter&) = delete;

  // Hands `block`, to be written at `at`, to the thread once the block before it is written, and gives
  // back in `block` that one's buffer, emptied. 0, or the errno of an earlier block's failure (then
  // `block` is not taken).
  int submit(std::vector<std::uint8_t>& block, zip_uint64_t at) {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return !full_; });
    if (error_) return error_;
    std::swap(block_, block);
    block.clear();
    at_ = at;
    full_ = true;
    lock.unlock();
    changed_.notify_all();
    return 0;
  }

  // Waits until every block handed over is written: 0, or the errno of the first failure.
  int drain() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return !full_; });
    return error_;
  }

private:
  void run() {
    sigset_t all;
    sigfillset(&all);
    pthread_sigmask(SIG_BLOCK, &all, nullptr);
    std::unique_lock lock(mutex_);
    for (;;) {
      changed_.wait(lock, [&] { return full_ || stop_; });
      if (!full_) return;  // stopped, nothing in flight
      lock.unlock();
      const int why = writeAt(fd_, block_, at_);  // block_ and at_ are this thread's while full_
      lock.lock();
      if (why && !error_) error_ = why;
      full_ = false;
      changed_.notify_all();
    }
  }

  int fd_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<std::uint8_t> block_;  // in flight while full_
  zip_uint64_t at_ = 0;
  bool full_ = false, stop_ = false;
  int error_ = 0;
  std::thread thread_;  // last: started once the members it reads are made
};

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
    try {
      // On one thread (--threads 1) the blocks are written in line: the process keeps to one core.
      if (tbb::this_task_arena::max_concurrency() > 1) writer_ = std::make_unique<BlockWriter>(fd_);
    } catch (const std::system_error& e) {  // no thread to be had: nothing may be thrown into libzip
      rollbackWrite();
      return failed(ZIP_ER_TMPOPEN, e.code().value());
    }
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
    if (const int why = writer_ ? writer_->drain() : 0) return failed(ZIP_ER_WRITE, why);
    writer_.reset();
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
    writer_.reset();  // its last block, if any, is written before the file goes
    ::close(std::exchange(fd_, -1));
    ::unlink(part_.c_str());
    return 0;
  }

  zip_int64_t remove() { return ::unlink(path_.c_str()) == 0 || errno == ENOENT ? 0 : failed(ZIP_ER_REMOVE, errno); }

private:
  zip_int64_t neverRead() { return failed(ZIP_ER_OPNOTSUPP, 0); }

  // Hands the tail to the block writer (or writes it, on one thread) and starts an empty one after it
  // (in the buffer of the block written before); false once a block could not be written (this one or,
  // by the block writer, an earlier one).
  bool flush() {
    if (tail_.empty()) return true;
    const std::size_t bytes = tail_.size();
    if (const int why = writer_ ? writer_->submit(tail_, tailStart_) : writeAt(fd_, tail_, tailStart_)) {
      failed(ZIP_ER_WRITE, why);
      return false;
    }
    tailStart_ += bytes;
    tail_.clear();  // written in line; handed over, it is the block before's buffer, already empty
    tail_.reserve(kTailBytes);
    return true;
  }

  fs::path path_, part_;
  int fd_ = -1;
  std::unique_ptr<BlockWriter> writer_;  // while fd_ is open, unless the blocks are written in line
  zip_uint64_t position_ = 0, end_ = 0;
  zip_uint64_t tailStart_ = 0;  // where tail_ goes in the file
  std::vector<std::uint8_t> tail_;
};

}  // namespace

zip_source_t* newArchiveSource(const fs::path& path, zip_error_t* error) {
  return makeZipSource(std::make_unique<ArchiveOutput>(path), error);
}

}  // namespace rodfab::printer_profiles
