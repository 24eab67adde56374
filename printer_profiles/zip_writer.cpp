#include "printer_profiles/zip_writer.hpp"

#include "printer_profiles/zip_output.hpp"
#include "printer_profiles/zip_source_adapter.hpp"

#include <zip.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;

namespace {

// A zip under construction with fixed timestamps and attributes; throws naming the archive.
class ZipBuilder {
public:
  explicit ZipBuilder(const fs::path& path) : path_(path) {
    zip_error_t ze;
    zip_error_init(&ze);
    if (zip_source_t* output = newArchiveSource(path, &ze)) {
      za_ = zip_open_from_source(output, ZIP_CREATE | ZIP_EXCL, &ze);
      if (!za_) zip_source_free(output);
    }
    if (!za_) {
      const std::string why = zip_error_strerror(&ze);
      zip_error_fini(&ze);
      throw std::runtime_error(path.string() + ": cannot create the zip archive (" + why + ")");
    }
    zip_error_fini(&ze);
  }
  ~ZipBuilder() {
    if (za_) zip_discard(za_);
  }
  ZipBuilder(const ZipBuilder&) = delete;
  ZipBuilder& operator=(const ZipBuilder&) = delete;

  zip_t* archive() const { return za_; }

  void add(const std::string& name, zip_source_t* source, ZipStorage storage) {
    if (!source) fail("cannot read the data of " + name);
    const zip_int64_t index = zip_file_add(za_, name.c_str(), source, ZIP_FL_ENC_UTF_8);
    if (index < 0) {
      zip_source_free(source);
      fail("cannot add " + name);
    }
    const auto i = static_cast<zip_uint64_t>(index);
    const bool deflate = storage == ZipStorage::Deflate;
    if (zip_set_file_compression(za_, i, deflate ? ZIP_CM_DEFLATE : ZIP_CM_STORE, deflate ? 1 : 0) != 0 ||
        zip_file_set_dostime(za_, i, kZipEntryTime.time, kZipEntryTime.date, 0) != 0 ||
        zip_file_set_external_attributes(za_, i, 0, ZIP_OPSYS_UNIX, 0100644u << 16) != 0)
      fail("cannot set the attributes of " + name);
  }

  // `failure`: what the entries' sources said went wrong, if anything (libzip's error names no entry).
  void close(const std::string& failure = {}) {
    if (zip_close(za_) != 0) {
      // The sources' own account names the entry and the reason; libzip's would only repeat the reason.
      if (!failure.empty()) throw std::runtime_error(path_.string() + ": cannot write the archive: " + failure);
      fail("cannot write the archive");
    }
    za_ = nullptr;
  }

  [[noreturn]] void fail(const std::string& what) {
    const std::string why = za_ ? zip_strerror(za_) : "";
    throw std::runtime_error(path_.string() + ": " + what + (why.empty() ? "" : " (" + why + ")"));
  }

private:
  fs::path path_;
  zip_t* za_ = nullptr;
};

// The staged file, opened once however many entries lie in it (a job's layers all do), and read through
// a read-ahead buffer: libzip asks for 8 KiB at a time and the entries lie one after another in it.
// Keeps the first failure of any entry read through it, naming the entry and the file, for the error
// writeZip throws.
class StagedFile {
public:
  explicit StagedFile(fs::path path) : path_(std::move(path)) {}
  ~StagedFile() {
    if (fd_ >= 0) ::close(fd_);
  }
  StagedFile(const StagedFile&) = delete;
  StagedFile& operator=(const StagedFile&) = delete;

  const fs::path& path() const { return path_; }

  // What went wrong reading the staged entries ("" while nothing did): the first failure noted.
  const std::string& failure() const { return failure_; }
  void noteFailure(const std::string& what) {
    if (failure_.empty()) failure_ = what;
  }

  // Opens the file unless it is open; false with errno set when it cannot be.
  bool open() {
    if (fd_ < 0) fd_ = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
    return fd_ >= 0;
  }

  // `length` bytes at `offset` of the opened file. False with errno set, or 0 when the file ends first.
  bool read(std::uint64_t offset, char* out, std::size_t length) {
    while (length > 0) {
      if (offset < aheadStart_ || offset >= aheadStart_ + ahead_.size())
        if (!fill(offset)) return false;
      const auto at = static_cast<std::size_t>(offset - aheadStart_);
      const std::size_t n = std::min(length, ahead_.size() - at);
      std::memcpy(out, ahead_.data() + at, n);
      out += n;
      offset += n;
      length -= n;
    }
    return true;
  }

private:
  static constexpr std::size_t kReadAhead = std::size_t{1} << 20;

  bool fill(std::uint64_t offset) {
    ahead_.resize(kReadAhead);
    std::size_t got = 0;
    while (got < kReadAhead) {
      const ssize_t n = ::pread(fd_, ahead_.data() + got, kReadAhead - got, static_cast<off_t>(offset + got));
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        ahead_.clear();
        return false;
      }
      if (n == 0) break;
      got += static_cast<std::size_t>(n);
    }
    ahead_.resize(got);
    aheadStart_ = offset;
    if (got == 0) errno = 0;
    return got > 0;
  }

  fs::path path_;
  std::string failure_;
  int fd_ = -1;
  std::vector<char> ahead_;
  std::uint64_t aheadStart_ = 0;
};

// A libzip source for StagedZipData: its stat says the data is already compressed (method, sizes and
// CRC), so zip_close copies the bytes instead of compressing them, as it does for zip_source_zip.
// Reads through `file`, which must outlive the source.
class StagedSource : public ZipSourceState {
public:
  static constexpr std::array kCommands{ZIP_SOURCE_OPEN, ZIP_SOURCE_READ, ZIP_SOURCE_CLOSE, ZIP_SOURCE_STAT,
                                        ZIP_SOURCE_GET_FILE_ATTRIBUTES};

  StagedSource(std::string name, StagedZipData data, ZipStorage storage, StagedFile& file)
      : name_(std::move(name)), data_(std::move(data)), storage_(storage), file_(file) {}

  zip_int64_t open() {
    position_ = 0;
    if (data_.inMemory) {
      if (data_.memory.size() == data_.length) return 0;
      return failedEntry(ZIP_ER_INCONS, 0, "its " + std::to_string(data_.memory.size()) + " bytes kept in memory, recorded as " +
                                               std::to_string(data_.length));
    }
    if (!data_.memory.empty())
      return failedEntry(ZIP_ER_INCONS, 0, "its " + std::to_string(data_.memory.size()) + " bytes are held in memory but its record places them in " +
                                               file_.path().string() + " at byte " + std::to_string(data_.offset));
    if (file_.open()) return 0;
    const int error = errno;  // before the message's allocations can touch it
    return failedEntry(ZIP_ER_OPEN, error, "cannot open " + file_.path().string() + " (" + std::strerror(error) + ")");
  }

  zip_int64_t close() { return 0; }  // StagedFile closes the file

  zip_int64_t read(void* data, zip_uint64_t length) {
    auto* out = static_cast<char*>(data);
    const zip_uint64_t want = std::min<zip_uint64_t>(length, data_.length - position_);
    if (data_.inMemory) {
      if (want > 0) std::memcpy(out, data_.memory.data() + position_, want);  // checked against `length` by open()
    } else if (!file_.read(data_.offset + position_, out, want)) {
      const int error = errno;  // before the message's allocations can touch it
      const std::string where = file_.path().string() + " at bytes " + std::to_string(data_.offset) + " to " +
                                std::to_string(data_.offset + data_.length);
      if (error) return failedEntry(ZIP_ER_READ, error, "cannot read " + where + " (" + std::strerror(error) + ")");
      return failedEntry(ZIP_ER_EOF, 0, where + ": the file ends first");  // shorter than recorded
    }
    position_ += want;
    return static_cast<zip_int64_t>(want);
  }

  zip_int64_t stat(zip_stat_t* st) const {
    zip_stat_init(st);
    st->size = data_.size;
    st->comp_size = data_.length;
    st->comp_method = storage_ == ZipStorage::Deflate ? ZIP_CM_DEFLATE : ZIP_CM_STORE;
    st->crc = data_.crc32;
    st->encryption_method = ZIP_EM_NONE;
    st->valid = ZIP_STAT_SIZE | ZIP_STAT_COMP_SIZE | ZIP_STAT_COMP_METHOD | ZIP_STAT_CRC | ZIP_STAT_ENCRYPTION_METHOD;
    return 0;
  }

  // Deflated entries say "fast" in general purpose bits 1-2, as libzip's own level-1 deflate does.
  zip_int64_t attributes(zip_file_attributes_t* a) const {
    if (storage_ != ZipStorage::Deflate) return 0;
    a->valid |= ZIP_FILE_ATTRIBUTES_GENERAL_PURPOSE_BIT_FLAGS;
    a->general_purpose_bit_flags = 2 << 1;
    a->general_purpose_bit_mask = 0x0006;
    return 0;
  }

private:
  // failed(), noting for writeZip's error which entry failed and why.
  zip_int64_t failedEntry(int code, int systemError, const std::string& why) {
    file_.noteFailure(name_ + ": " + why);
    return failed(code, systemError);
  }

  std::string name_;  // the entry's, in the archive
  StagedZipData data_;
  ZipStorage storage_;
  StagedFile& file_;
  zip_uint64_t position_ = 0;
};

zip_source_t* stagedSource(zip_t* za, const std::string& name, const StagedZipData& data, ZipStorage storage, StagedFile& file) {
  return makeZipSource(za, std::make_unique<StagedSource>(name, data, storage, file));
}

}  // namespace

void writeZip(const fs::path& zipPath, const std::vector<ZipEntry>& entries, const fs::path& stagedFile) {
  StagedFile staged(stagedFile);  // declared first: the zip's sources, which read through it, go before it
  ZipBuilder zip(zipPath);
  for (const ZipEntry& e : entries) {
    if (e.staged && e.staged->storage != e.storage)
      throw std::logic_error("writeZip: entry " + e.name + " is staged as one method and listed as the other");
    zip_source_t* source = e.staged ? stagedSource(zip.archive(), e.name, *e.staged, e.storage, staged)
                                    : zip_source_file(zip.archive(), e.source.c_str(), 0, -1);
    zip.add(e.name, source, e.storage);
  }
  zip.close(staged.failure());
}

void writeZipFromMemory(const fs::path& zipPath, const std::vector<ZipMemoryEntry>& entries) {
  ZipBuilder zip(zipPath);
  for (const ZipMemoryEntry& e : entries)
    zip.add(e.name, zip_source_buffer(zip.archive(), e.data.data(), e.data.size(), 0), e.storage);
  zip.close();
}

}  // namespace rodfab::printer_profiles
