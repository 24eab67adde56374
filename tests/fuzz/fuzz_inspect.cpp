// libFuzzer target: `inspect` on hostile jobs, as a zip and as a folder. The input is a zip archive. It is
// inspected as it is, then unpacked by this harness into a folder (entries whose Unix mode says link or
// FIFO become links and FIFOs; unsafe names are skipped; CRC errors ignored, so mutated bytes of stored
// entries arrive) with the manifest's checksums recomputed for the files present, so that the folder's
// inspection reaches the image decoders and layout checks. inspect must never crash, hang, throw or
// grow memory without bound; its defects must be printable; a zip it passes must pass as a folder too.
#include "common/xxh128.hpp"
#include "printer_profiles/printer_profiles.hpp"

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <zip.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <string>

namespace fs = std::filesystem;
namespace pp = rodfab::printer_profiles;
using nlohmann::json;

namespace {

constexpr std::size_t kMaxEntries = 256;
constexpr std::size_t kMaxEntryBytes = 1 << 20, kMaxUnpackedBytes = 4 << 20;

fs::path workDir() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("rodfab-fuzz-inspect-" + std::to_string(::getpid()));
    fs::create_directories(d);
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(fs::temp_directory_path() / ("rodfab-fuzz-inspect-" + std::to_string(::getpid())), ec);
    });
    return d;
  }();
  return dir;
}

void writeFile(const fs::path& file, const std::uint8_t* data, std::size_t size) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
}

// Names this harness will create: relative, no '.' or '..' or empty components, two folders deep at most.
bool harmlessName(const std::string& name) {
  if (name.empty() || name.size() > 200 || name.front() == '/' || name.find('\0') != std::string::npos) return false;
  int depth = 0;
  for (std::size_t start = 0; start <= name.size();) {
    const std::size_t slash = std::min(name.find('/', start), name.size());
    const std::string part = name.substr(start, slash - start);
    if (part == "." || part == ".." || (part.empty() && slash != name.size())) return false;
    start = slash + 1;
    ++depth;
  }
  return depth <= 3;
}

// The entry's bytes as far as they can be read (a CRC error at the end does not discard them).
std::string readEntry(zip_t* za, zip_uint64_t index) {
  std::string data;
  zip_file_t* zf = zip_fopen_index(za, index, 0);
  if (!zf) return data;
  char buffer[16384];
  zip_int64_t got = 0;
  while (data.size() < kMaxEntryBytes && (got = zip_fread(zf, buffer, sizeof buffer)) > 0) data.append(buffer, static_cast<std::size_t>(got));
  zip_fclose(zf);
  return data;
}

void unpackEntry(zip_t* za, zip_uint64_t index, const fs::path& root, std::size_t& unpacked) {
  const char* rawName = zip_get_name(za, index, ZIP_FL_ENC_RAW);
  if (!rawName || !harmlessName(rawName)) return;
  const std::string name = rawName;
  const fs::path target = root / name;
  std::error_code ec;
  fs::create_directories(target.parent_path(), ec);
  if (name.back() == '/') {
    fs::create_directories(target, ec);
    return;
  }
  zip_uint8_t opsys = 0;
  zip_uint32_t attributes = 0;
  zip_file_get_external_attributes(za, index, 0, &opsys, &attributes);
  const mode_t type = opsys == ZIP_OPSYS_UNIX ? static_cast<mode_t>(attributes >> 16) & S_IFMT : 0;
  const std::string data = readEntry(za, index);
  unpacked += data.size();
  if (type == S_IFLNK) fs::create_symlink(data.substr(0, 100), target, ec);  // inspect must not follow it
  else if (type == S_IFIFO) ::mkfifo(target.c_str(), 0644);                  // nor open it
  else writeFile(target, reinterpret_cast<const std::uint8_t*>(data.data()), data.size());
}

// The input unpacked into `root`; false when it is no zip libzip opens.
bool unpack(const std::uint8_t* data, std::size_t size, const fs::path& root) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* source = zip_source_buffer_create(data, size, 0, &error);
  zip_t* za = source ? zip_open_from_source(source, ZIP_RDONLY, &error) : nullptr;
  zip_error_fini(&error);
  if (!za) {
    if (source) zip_source_free(source);
    return false;
  }
  fs::create_directories(root);
  std::size_t unpacked = 0;
  const zip_int64_t count = zip_get_num_entries(za, 0);
  for (zip_int64_t n = 0; n < count && n < static_cast<zip_int64_t>(kMaxEntries) && unpacked < kMaxUnpackedBytes; ++n)
    unpackEntry(za, static_cast<zip_uint64_t>(n), root, unpacked);
  zip_discard(za);
  return true;
}

// Recomputes the manifest's size and checksum of every listed regular file that is present.
void fixChecksums(const fs::path& root) {
  const fs::path manifestPath = root / "manifest.json";
  std::error_code ec;
  if (!fs::is_regular_file(fs::symlink_status(manifestPath, ec))) return;
  std::ifstream in(manifestPath, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const json::parser_callback_t shallow = [](int depth, json::parse_event_t, json&) {
    if (depth > 32) throw std::runtime_error("deep");
    return true;
  };
  json manifest;
  try {
    manifest = json::parse(text, shallow);
  } catch (const std::exception&) {
    return;
  }
  if (!manifest.is_object() || !manifest.contains("files") || !manifest["files"].is_object()) return;
  for (auto& [name, row] : manifest["files"].items()) {
    const fs::path file = root / name;
    if (!harmlessName(name) || !fs::is_regular_file(fs::symlink_status(file, ec))) continue;
    std::ifstream f(file, std::ios::binary);
    const pp::Bytes bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    row = {{"bytes", bytes.size()}, {"xxh128", rodfab::common::xxh128Hex(bytes)}};
  }
  const std::string fixed = manifest.dump(1, ' ', false, json::error_handler_t::replace);
  writeFile(manifestPath, reinterpret_cast<const std::uint8_t*>(fixed.data()), fixed.size());
}

void checkReport(const pp::InspectReport& report) {
  for (const std::string& d : report.defects)
    for (const char c : d)
      if (c < 0x20 || c == 0x7f) std::abort();  // names from the job must arrive escaped
  if (report.ok() && (report.layers <= 0 || report.materials.size() < 2 || report.materials.size() > 3)) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static tbb::global_control oneThread(tbb::global_control::max_allowed_parallelism, 1);  // reproducible runs
  const fs::path zipJob = workDir() / "job.zip", folderJob = workDir() / "job";
  writeFile(zipJob, data, size);
  const pp::InspectReport asZip = pp::inspectJob(zipJob);
  checkReport(asZip);

  std::error_code ec;
  fs::remove_all(folderJob, ec);
  if (unpack(data, size, folderJob)) {
    fixChecksums(folderJob);
    const pp::InspectReport asFolder = pp::inspectJob(folderJob);
    checkReport(asFolder);
    if (asZip.ok() && !asFolder.ok()) std::abort();  // the same sound job, unpacked
    if (asZip.ok())
      for (std::size_t n = 0; n < asZip.materials.size(); ++n)
        if (asZip.materials[n].voxels != asFolder.materials[n].voxels) std::abort();
    fs::remove_all(folderJob, ec);
  }
  return 0;
}
