#include "printer_profiles/job_archive.hpp"

#include "printer_profiles/zip_pool.hpp"

#include <nlohmann/json.hpp>
#include <zip.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <mutex>
#include <map>
#include <optional>
#include <set>
#include <string_view>
#include <utility>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;

const char* toString(ArchiveFormat format) { return format == ArchiveFormat::Zip ? "zip" : "dir"; }

namespace {

class DirectoryJobFiles final : public JobFiles {
public:
  explicit DirectoryJobFiles(fs::path root) : root_(std::move(root)) {
    for (const auto& entry : fs::recursive_directory_iterator(root_))
      if (entry.is_regular_file()) names_.push_back(entry.path().lexically_relative(root_).generic_string());
    std::sort(names_.begin(), names_.end());
  }
  const fs::path& path() const override { return root_; }
  ArchiveFormat format() const override { return ArchiveFormat::Directory; }
  std::vector<std::string> names() const override { return names_; }
  bool contains(const std::string& name) const override {
    return std::binary_search(names_.begin(), names_.end(), name);
  }
  Bytes read(const std::string& name) const override {
    std::ifstream in(root_ / name, std::ios::binary);
    if (!in) throw JobReadError(root_.string() + ": cannot open " + name);
    Bytes data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) throw JobReadError(root_.string() + ": cannot read " + name);
    return data;
  }

private:
  fs::path root_;
  std::vector<std::string> names_;
};

// libzip handles are not thread-safe: readers borrow one from a pool.
class ZipJobFiles final : public JobFiles {
public:
  explicit ZipJobFiles(fs::path file) : file_(std::move(file)), pool_([this] { return open(); }) {
    zip_t* za = open();
    const zip_int64_t count = zip_get_num_entries(za, 0);
    for (zip_int64_t n = 0; n < count; ++n) {
      const char* name = zip_get_name(za, static_cast<zip_uint64_t>(n), 0);
      if (name && *name && name[std::strlen(name) - 1] != '/') names_.push_back(name);
    }
    std::sort(names_.begin(), names_.end());
    pool_.giveBack(za);
  }
  const fs::path& path() const override { return file_; }
  ArchiveFormat format() const override { return ArchiveFormat::Zip; }
  std::vector<std::string> names() const override { return names_; }
  bool contains(const std::string& name) const override {
    return std::binary_search(names_.begin(), names_.end(), name);
  }
  Bytes read(const std::string& name) const override {
    const ZipPool::Lease za(pool_);
    return readEntry(za.get(), name);
  }

private:
  zip_t* open() const {
    int error = 0;
    zip_t* za = zip_open(file_.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &error);
    if (!za) {
      zip_error_t ze;
      zip_error_init_with_code(&ze, error);
      const std::string why = zip_error_strerror(&ze);
      zip_error_fini(&ze);
      throw JobReadError(file_.string() + ": not a readable zip archive (" + why + "); it may be truncated or damaged");
    }
    return za;
  }
  Bytes readEntry(zip_t* za, const std::string& name) const {
    const zip_int64_t index = zip_name_locate(za, name.c_str(), 0);
    zip_stat_t st;
    if (index < 0 || zip_stat_index(za, static_cast<zip_uint64_t>(index), 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE))
      throw JobReadError(file_.string() + ": has no entry " + name);
    zip_file_t* zf = zip_fopen_index(za, static_cast<zip_uint64_t>(index), 0);
    if (!zf) throw JobReadError(file_.string() + ": cannot open entry " + name + " (" + zip_strerror(za) + ")");
    Bytes data(st.size);
    const zip_int64_t got = zip_fread(zf, data.data(), data.size());
    // Reading to the end makes libzip check the CRC: ask for one byte more.
    std::uint8_t extra = 0;
    const zip_int64_t more = got == static_cast<zip_int64_t>(data.size()) ? zip_fread(zf, &extra, 1) : 0;
    const std::string why = got < 0 || more < 0 ? zip_file_strerror(zf) : "";
    zip_fclose(zf);
    if (got != static_cast<zip_int64_t>(data.size()) || more != 0)
      throw JobReadError(file_.string() + ": entry " + name + " is damaged" + (why.empty() ? "" : " (" + why + ")"));
    return data;
  }

  fs::path file_;
  std::vector<std::string> names_;
  ZipPool pool_;
};

}  // namespace

std::unique_ptr<JobFiles> openJobFiles(const fs::path& job) {
  std::error_code ec;
  if (fs::is_directory(job, ec)) return std::make_unique<DirectoryJobFiles>(job);
  if (!fs::exists(job, ec)) throw JobReadError(job.string() + ": no such job (expected a .zip archive or a directory)");
  return std::make_unique<ZipJobFiles>(job);
}

namespace {

// A zip under construction with fixed timestamps and attributes; throws naming the archive.
class ZipBuilder {
public:
  explicit ZipBuilder(const fs::path& path) : path_(path) {
    int error = 0;
    za_ = zip_open(path.c_str(), ZIP_CREATE | ZIP_EXCL, &error);
    if (!za_) {
      zip_error_t ze;
      zip_error_init_with_code(&ze, error);
      const std::string why = zip_error_strerror(&ze);
      zip_error_fini(&ze);
      throw std::runtime_error(path.string() + ": cannot create the zip archive (" + why + ")");
    }
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
        zip_file_set_mtime(za_, i, static_cast<time_t>(kZipEntryTime), 0) != 0 ||
        zip_file_set_external_attributes(za_, i, 0, ZIP_OPSYS_UNIX, 0100644u << 16) != 0)
      fail("cannot set the attributes of " + name);
  }

  void close() {
    if (zip_close(za_) != 0) fail("cannot write the archive");
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

}  // namespace

namespace {

// The staged files, each opened once however many entries it holds (a job's layers are all in one).
class StagedFiles {
public:
  StagedFiles() = default;
  ~StagedFiles() {
    for (const auto& [path, fd] : fds_) ::close(fd);
  }
  StagedFiles(const StagedFiles&) = delete;
  StagedFiles& operator=(const StagedFiles&) = delete;

  // The file's descriptor, or -1 with errno set.
  int open(const fs::path& file) {
    if (const auto it = fds_.find(file); it != fds_.end()) return it->second;
    const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd >= 0) fds_.emplace(file, fd);
    return fd;
  }

private:
  std::map<fs::path, int> fds_;
};

// A libzip source for StagedZipData: its stat says the data is already compressed (method, sizes and
// CRC), so zip_close copies the bytes instead of compressing them, as it does for zip_source_zip.
// Reads through `files`, which must outlive the source.
class StagedSource {
public:
  StagedSource(StagedZipData data, ZipStorage storage, StagedFiles& files)
      : data_(std::move(data)), storage_(storage), files_(files) {
    zip_error_init(&error_);
  }
  ~StagedSource() { zip_error_fini(&error_); }
  StagedSource(const StagedSource&) = delete;
  StagedSource& operator=(const StagedSource&) = delete;

  static zip_int64_t callback(void* self, void* data, zip_uint64_t length, zip_source_cmd_t command) {
    auto* source = static_cast<StagedSource*>(self);
    if (command == ZIP_SOURCE_FREE) {
      delete source;
      return 0;
    }
    return source->handle(data, length, command);
  }

private:
  zip_int64_t handle(void* data, zip_uint64_t length, zip_source_cmd_t command) {
    switch (command) {
      case ZIP_SOURCE_OPEN:
        fd_ = files_.open(data_.file);
        position_ = 0;
        return fd_ >= 0 ? 0 : failed(ZIP_ER_OPEN);
      case ZIP_SOURCE_READ: return read(static_cast<char*>(data), length);
      case ZIP_SOURCE_CLOSE:
        fd_ = -1;  // StagedFiles closes it
        return 0;
      case ZIP_SOURCE_STAT: return stat(static_cast<zip_stat_t*>(data));
      case ZIP_SOURCE_GET_FILE_ATTRIBUTES: return attributes(static_cast<zip_file_attributes_t*>(data));
      case ZIP_SOURCE_ERROR: return zip_error_to_data(&error_, data, length);
      case ZIP_SOURCE_SUPPORTS:
        return zip_source_make_command_bitmap(ZIP_SOURCE_OPEN, ZIP_SOURCE_READ, ZIP_SOURCE_CLOSE, ZIP_SOURCE_STAT,
                                              ZIP_SOURCE_ERROR, ZIP_SOURCE_FREE, ZIP_SOURCE_GET_FILE_ATTRIBUTES, -1);
      default: return failed(ZIP_ER_OPNOTSUPP);
    }
  }

  zip_int64_t failed(int code) {
    zip_error_set(&error_, code, code == ZIP_ER_OPEN || code == ZIP_ER_READ ? errno : 0);
    return -1;
  }

  zip_int64_t read(char* out, zip_uint64_t length) {
    const zip_uint64_t want = std::min<zip_uint64_t>(length, data_.length - position_);
    zip_uint64_t got = 0;
    while (got < want) {
      const ssize_t n = ::pread(fd_, out + got, want - got, static_cast<off_t>(data_.offset + position_ + got));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return failed(n < 0 ? ZIP_ER_READ : ZIP_ER_EOF);  // the staged file is shorter than recorded
      got += static_cast<zip_uint64_t>(n);
    }
    position_ += got;
    return static_cast<zip_int64_t>(got);
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

  StagedZipData data_;
  ZipStorage storage_;
  StagedFiles& files_;
  zip_error_t error_;
  int fd_ = -1;
  zip_uint64_t position_ = 0;
};

zip_source_t* stagedSource(zip_t* za, const StagedZipData& data, ZipStorage storage, StagedFiles& files) {
  auto* source = new StagedSource(data, storage, files);
  zip_source_t* zs = zip_source_function(za, StagedSource::callback, source);
  if (!zs) delete source;
  return zs;
}

}  // namespace

void writeZip(const fs::path& zipPath, const std::vector<ZipEntry>& entries) {
  StagedFiles staged;  // declared first: the zip's sources, which read through it, go before it
  ZipBuilder zip(zipPath);
  for (const ZipEntry& e : entries) {
    zip_source_t* source = e.staged ? stagedSource(zip.archive(), *e.staged, e.storage, staged)
                                    : zip_source_file(zip.archive(), e.source.c_str(), 0, -1);
    zip.add(e.name, source, e.storage);
  }
  zip.close();
}

void writeZipFromMemory(const fs::path& zipPath, const std::vector<ZipMemoryEntry>& entries) {
  ZipBuilder zip(zipPath);
  for (const ZipMemoryEntry& e : entries)
    zip.add(e.name, zip_source_buffer(zip.archive(), e.data.data(), e.data.size(), 0), e.storage);
  zip.close();
}

}  // namespace rodfab::printer_profiles

namespace rodfab::printer_profiles {

namespace {

// Only what tells a rodfab job, read as SAX events (no document is built): the top-level "format" and
// the names in the top-level "files" table. Stops at nesting deeper than a manifest has.
class ManifestSummary final : public nlohmann::json_sax<nlohmann::json> {
public:
  std::string format;
  std::set<std::string> files;

  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool string(string_t& value) override {
    if (depth_ == 1 && topKey_ == "format") format = value;
    return true;
  }
  bool start_object(std::size_t) override { return enter(); }
  bool start_array(std::size_t) override { return enter(); }
  bool key(string_t& name) override {
    if (depth_ == 1) topKey_ = name;
    else if (depth_ == 2 && inFiles_) files.insert(name);
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
    if (depth_ == 2) inFiles_ = false;
    --depth_;
    return true;
  }
  int depth_ = 0;
  std::string topKey_;
  bool inFiles_ = false;
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
  return "";
}

// A zip is a rodfab job when its first entry is manifest.json (the writer's fixed order) of the job
// format. The local header is looked at first (46 bytes), so a large foreign zip is not read at all.
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
  zip_discard(za);
  if (!summarizeManifest(text)) return std::string("a zip archive whose ") + kManifestName + " is not a rodfab job manifest (" + kJobFormat + ")";
  return "";
}

}  // namespace

OutputOccupant examineOutput(const fs::path& path) {
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

}  // namespace rodfab::printer_profiles
