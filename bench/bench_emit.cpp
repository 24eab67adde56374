// The job archive's file work alone (printer_profiles/zip_writer.cpp, zip_output.cpp, zip_input.cpp), at
// the spring benchmark's shape: 6,000 layer images of ~6.7 KB as zip forms (40 MB, the spring job's
// zip), written into a new archive and read back raw as the writer's verification does. The _libzip
// variants do the same through libzip's own stdio file source, for comparison.
#include "printer_profiles/deflate.hpp"
#include "printer_profiles/job_reader.hpp"
#include "printer_profiles/zip_writer.hpp"

#include <benchmark/benchmark.h>
#include <zip.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

namespace fs = std::filesystem;
namespace pp = rodfab::printer_profiles;

namespace {

constexpr int kEntries = 6000;
constexpr std::size_t kEntryBytes = 6700;

// A scratch folder of this process's, removed when the program exits.
struct ScratchDir {
  fs::path path = fs::temp_directory_path() / ("rodfab-bench-emit-" + std::to_string(::getpid()));
  ScratchDir() { fs::create_directories(path); }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

const fs::path& benchDir() {
  static const ScratchDir dir;
  return dir.path;
}

// The entries' bytes, as stored (zip "store": the bytes are their own zip form).
const std::vector<pp::Bytes>& images() {
  static const std::vector<pp::Bytes> all = [] {
    std::mt19937 rng(3);
    std::vector<pp::Bytes> v(kEntries, pp::Bytes(kEntryBytes));
    for (pp::Bytes& b : v)
      for (auto& x : b) x = static_cast<std::uint8_t>(rng());
    return v;
  }();
  return all;
}

std::string layerName(int n) { return "layers/" + std::to_string(n) + ".png"; }

// The entries staged one after another in one file, as the band encoder stages a job's layers.
const std::vector<pp::ZipEntry>& stagedEntries() {
  static const std::vector<pp::ZipEntry> entries = [] {
    const fs::path staged = benchDir() / "layers.bin";
    std::ofstream out(staged, std::ios::binary);
    std::vector<pp::ZipEntry> v;
    std::uint64_t offset = 0;
    for (int n = 0; n < kEntries; ++n) {
      const pp::Bytes& b = images()[static_cast<std::size_t>(n)];
      out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
      v.push_back({layerName(n), {}, pp::ZipStorage::Store,
                   pp::StagedZipData{.offset = offset, .length = b.size(), .size = b.size(), .crc32 = pp::zipCrc32(b), .storage = pp::ZipStorage::Store}});
      offset += b.size();
    }
    return v;
  }();
  return entries;
}

void setBytes(benchmark::State& state) {
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * kEntries * static_cast<std::int64_t>(kEntryBytes));
}

void BM_WriteStagedZip(benchmark::State& state) {
  const auto& entries = stagedEntries();
  for (auto _ : state) {
    fs::remove(benchDir() / "job.zip");
    pp::writeZip(benchDir() / "job.zip", entries, benchDir() / "layers.bin");
  }
  setBytes(state);
}

// libzip's file output, from memory (no staged reads): the output side alone.
void BM_WriteZip_libzip(benchmark::State& state) {
  for (auto _ : state) {
    fs::remove(benchDir() / "libzip.zip");
    int error = 0;
    zip_t* za = zip_open((benchDir() / "libzip.zip").c_str(), ZIP_CREATE | ZIP_EXCL, &error);
    for (int n = 0; n < kEntries; ++n) {
      const pp::Bytes& b = images()[static_cast<std::size_t>(n)];
      const zip_int64_t i = zip_file_add(za, layerName(n).c_str(), zip_source_buffer(za, b.data(), b.size(), 0), ZIP_FL_ENC_UTF_8);
      zip_set_file_compression(za, static_cast<zip_uint64_t>(i), ZIP_CM_STORE, 0);
      zip_file_set_dostime(za, static_cast<zip_uint64_t>(i), pp::kZipEntryTime.time, pp::kZipEntryTime.date, 0);
    }
    if (zip_close(za) != 0) state.SkipWithError("zip_close failed");
  }
  setBytes(state);
}

// The same through the archive writer's output (zip_output.hpp).
void BM_WriteZipFromMemory(benchmark::State& state) {
  std::vector<pp::ZipMemoryEntry> entries;
  for (int n = 0; n < kEntries; ++n) entries.push_back({layerName(n), images()[static_cast<std::size_t>(n)], pp::ZipStorage::Store});
  for (auto _ : state) {
    fs::remove(benchDir() / "memory.zip");
    pp::writeZipFromMemory(benchDir() / "memory.zip", entries);
  }
  setBytes(state);
}

// Opening (ZIP_CHECKCONS) and reading every entry's stored bytes, as the verification does.
void BM_ReadBackStored(benchmark::State& state) {
  if (!fs::exists(benchDir() / "job.zip")) pp::writeZip(benchDir() / "job.zip", stagedEntries(), benchDir() / "layers.bin");
  for (auto _ : state) {
    const auto reader = pp::openJobReader(benchDir() / "job.zip", 100'000, 4);
    std::uint64_t bytes = 0;
    for (const pp::JobEntry& e : reader->entries())
      reader->streamStored(e, 1 << 20, [&](std::span<const std::uint8_t> piece) { bytes += piece.size(); });
    benchmark::DoNotOptimize(bytes);
  }
  setBytes(state);
}

// Opening alone (ZIP_CHECKCONS: libzip reads the directory and every entry's local header).
void BM_OpenChecked(benchmark::State& state) {
  if (!fs::exists(benchDir() / "job.zip")) pp::writeZip(benchDir() / "job.zip", stagedEntries(), benchDir() / "layers.bin");
  for (auto _ : state) benchmark::DoNotOptimize(pp::openJobReader(benchDir() / "job.zip", 100'000, 4)->entries().size());
  setBytes(state);
}

void BM_ReadBackStored_libzip(benchmark::State& state) {
  if (!fs::exists(benchDir() / "job.zip")) pp::writeZip(benchDir() / "job.zip", stagedEntries(), benchDir() / "layers.bin");
  std::vector<std::uint8_t> buffer(64 * 1024);
  for (auto _ : state) {
    int error = 0;
    zip_t* za = zip_open((benchDir() / "job.zip").c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &error);
    const zip_int64_t count = zip_get_num_entries(za, 0);
    for (zip_int64_t n = 0; n < count; ++n) {
      zip_file_t* zf = zip_fopen_index(za, static_cast<zip_uint64_t>(n), ZIP_FL_COMPRESSED);
      while (zip_fread(zf, buffer.data(), buffer.size()) > 0) {
      }
      zip_fclose(zf);
    }
    zip_discard(za);
  }
  setBytes(state);
}

}  // namespace

BENCHMARK(BM_WriteStagedZip)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WriteZip_libzip)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WriteZipFromMemory)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadBackStored)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_OpenChecked)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadBackStored_libzip)->Unit(benchmark::kMillisecond)->UseRealTime();
