// Internal to printer_profiles/: what the job writer records per layer and file, and the job's
// manifest.json built from it (the format `inspect` reads back; printer_profiles/README.md).
#pragma once

#include "printer_profiles/job_archive.hpp"
#include "printer_profiles/job_layout.hpp"
#include "printer_profiles/job_writer.hpp"
#include "printer_profiles/profile.hpp"

#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>

#include <array>
#include <bit>
#include <cstdint>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

// Per byte of 8 voxels (x = 0 in bit 7): how many are set and the sum of their x. A table, because
// the build targets CPUs without a popcount instruction and Moments::add runs for every row of every leaf.
// inspect_layers.cpp builds its own tables (kBitCounts, kBitPositionSums) on purpose: the inspector is
// the writer's independent check, so it shares none of the writer's arithmetic with what it checks.
struct BitSums {
  std::uint8_t count = 0, sumX = 0;
};
inline constexpr std::array<BitSums, 256> kBitSums = [] {
  std::array<BitSums, 256> table{};
  for (int bits = 0; bits < 256; ++bits)
    for (int x = 0; x < 8; ++x)
      if ((bits >> (7 - x)) & 1) {
        ++table[static_cast<std::size_t>(bits)].count;
        table[static_cast<std::size_t>(bits)].sumX = static_cast<std::uint8_t>(table[static_cast<std::size_t>(bits)].sumX + x);
      }
  return table;
}();

// Integer sums of voxel indices: exact, so order and thread count cannot change them.
struct Moments {
  std::uint64_t count = 0;
  std::int64_t sum[3] = {0, 0, 0};
  openvdb::Coord min = openvdb::Coord::max(), max = openvdb::Coord::min();

  // The 8 voxels (i = firstI .. firstI + 7, most significant bit first) of row j, layer k set in `bits`.
  void add(std::uint8_t bits, int firstI, int j, int k) {
    if (!bits) return;
    const int n = kBitSums[bits].count, sumX = kBitSums[bits].sumX;
    count += static_cast<std::uint64_t>(n);
    sum[0] += static_cast<std::int64_t>(n) * firstI + sumX;
    sum[1] += static_cast<std::int64_t>(n) * j;
    sum[2] += static_cast<std::int64_t>(n) * k;
    const openvdb::Coord lo(firstI + std::countl_zero(bits), j, k), hi(firstI + 7 - std::countr_zero(bits), j, k);
    min.minComponent(lo);
    max.maxComponent(hi);
  }
  // add() of the 8 rows j = firstJ .. firstJ + 7 of a leaf at once (row j's bits in byte j - firstJ of
  // `rows`): the same sums, by counting bits under masks (the voxels whose row, or whose bit within its
  // byte, has bit 0, 1 or 2 set) instead of a table look-up per row, and the corners found once. Fast
  // where it is compiled for CPUs with a popcount instruction (the band encoder's rasterize is).
  void addRows(std::uint64_t rows, int firstI, int firstJ, int k) {
    if (!rows) return;
    const auto bitsUnder = [rows](std::uint64_t mask) { return static_cast<std::int64_t>(std::popcount(rows & mask)); };
    const std::int64_t n = bitsUnder(~std::uint64_t{0});
    const std::int64_t sumY = bitsUnder(0xff00ff00ff00ff00u) + 2 * bitsUnder(0xffff0000ffff0000u) + 4 * bitsUnder(0xffffffff00000000u);
    // x = 7 - (the bit's place in its byte)
    const std::int64_t sumX = 7 * n - (bitsUnder(0xaaaaaaaaaaaaaaaau) + 2 * bitsUnder(0xccccccccccccccccu) + 4 * bitsUnder(0xf0f0f0f0f0f0f0f0u));
    std::uint64_t any = rows | rows >> 32;  // the columns set in any row, in the low byte
    any |= any >> 16;
    any |= any >> 8;
    count += static_cast<std::uint64_t>(n);
    sum[0] += n * firstI + sumX;
    sum[1] += n * firstJ + sumY;
    sum[2] += n * k;
    const int yLow = std::countr_zero(rows) / 8, yHigh = (63 - std::countl_zero(rows)) / 8;
    const auto columns = static_cast<std::uint8_t>(any);
    min.minComponent(openvdb::Coord(firstI + std::countl_zero(columns), firstJ + yLow, k));
    max.maxComponent(openvdb::Coord(firstI + 7 - std::countr_zero(columns), firstJ + yHigh, k));
  }
  void merge(const Moments& o) {
    count += o.count;
    for (int a = 0; a < 3; ++a) sum[a] += o.sum[a];
    min.minComponent(o.min);
    max.maxComponent(o.max);
  }
};

struct FileRecord {
  std::string name;
  std::uintmax_t bytes = 0;
  std::string xxh128;  // of the bytes as written (common/xxh128.hpp: 32 lowercase hex digits)
};

struct LayerRecord {
  std::array<std::uint64_t, 3> voxels{};  // by MaterialRole
  std::array<Moments, 2> moments;         // rigid, rubbery, from the grid
  std::vector<FileRecord> files;          // in profile material order
  std::vector<StagedZipData> zipped;      // zip jobs: each file's zip form, staged with its band
};

// The job's layer images, fixed when the writer starts: what the band encoder makes and the manifest
// describes.
struct LayerImageForm {
  const JobGeometry& geometry;
  ImageFormat imageFormat;
  SupportPolicy support;
  const std::vector<const ProfileMaterial*>& emitted;  // materials with bitmap stacks, in profile order
};

// Everything the manifest says, as the writer holds it.
struct ManifestInputs {
  const JobSpec& spec;
  LayerImageForm form;
  const std::vector<LayerRecord>& layers;               // every layer of the job, bottom-up
  const std::vector<int>& contactLayers;                // the contact sheet's layers
};

// manifest.json: `files` is its file table (every file but the manifest; empty for the version the
// job report is made from), `previewNames` the previews' names in the job.
nlohmann::json jobManifest(const ManifestInputs& in, const std::vector<FileRecord>& files,
                           const std::vector<std::string>& previewNames);

}  // namespace rodfab::printer_profiles
