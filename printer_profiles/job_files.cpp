#include "printer_profiles/job_files.hpp"

#include "printer_profiles/zip_pool.hpp"

#include <zip.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>
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

}  // namespace rodfab::printer_profiles
