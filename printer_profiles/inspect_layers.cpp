// The layer images of a job: decoded and checked in parallel (size, resolution, voxel counts, no voxel
// of two materials), then the part's position recomputed from them against the manifest's.
#include "common/file_hasher.hpp"
#include "common/interrupt.hpp"
#include "printer_profiles/gcvf_writer.hpp"
#include "printer_profiles/inspect_gcvf.hpp"
#include "printer_profiles/inspector.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <bit>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>
#include <string_view>

namespace rodfab::printer_profiles::detail {

namespace {

// Layers are checked in parallel, but never more at once than their capped images fit in this budget.
constexpr std::uint64_t kLayerMemoryBudget = 512ull << 20;

// Per byte value: pixels set, and the sum of their positions (0 = most significant bit). The writer has
// the same figures in job_manifest.hpp's kBitSums; these are built apart on purpose: the inspector is
// the writer's independent check, and a table shared with the writer could not catch the writer's error.
constexpr std::array<std::uint8_t, 256> kBitCounts = [] {
  std::array<std::uint8_t, 256> t{};
  for (int v = 0; v < 256; ++v) t[static_cast<std::size_t>(v)] = static_cast<std::uint8_t>(std::popcount(static_cast<unsigned>(v)));
  return t;
}();
constexpr std::array<std::uint8_t, 256> kBitPositionSums = [] {
  std::array<std::uint8_t, 256> t{};
  for (int v = 0; v < 256; ++v)
    for (int x = 0; x < 8; ++x)
      if ((v >> (7 - x)) & 1) t[static_cast<std::size_t>(v)] = static_cast<std::uint8_t>(t[static_cast<std::size_t>(v)] + x);
  return t;
}();

std::string fmt3(const std::array<double, 3>& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.4f, %.4f, %.4f)", v[0], v[1], v[2]);
  return buf;
}

}  // namespace

struct Inspector::RepeatedImage {
  std::once_flag first;
  bool blank = false;  // the first copy was read, checked and decoded clean, without a voxel
  std::string storedXxh128;
  std::uint64_t storedBytes = 0;
  StoredEntryInfo directory;
};

void Inspector::findRepeatedImages() {
  if (gcvf() || reader_->format() != ArchiveFormat::Zip) return;
  std::map<std::string, std::vector<std::string>> byContents;  // listed digest and size -> image names
  for (int l = 0; l < layout_.layers; ++l)
    for (const ProfileMaterial* m : layout_.materials) {
      const std::string name = profile_.layerFileName(*m, l, layout_.imageFormat);
      const auto listed = layout_.listed.find(name);
      if (listed != layout_.listed.end())
        byContents[listed->second.digest.hex + ' ' + std::to_string(listed->second.bytes)].push_back(name);
    }
  for (const auto& [contents, names] : byContents) {
    if (names.size() < 2) continue;
    const auto group = std::make_shared<RepeatedImage>();
    for (const std::string& name : names) repeated_[name] = group;
  }
}

// Whether `name`'s stored bytes and directory record are `first`'s (`record`: take them as `first`'s).
bool Inspector::storedLike(const std::string& name, RepeatedImage& first, bool record) const {
  const auto file = files_.find(name);
  if (file == files_.end()) return false;
  common::FileHasher digest(common::HashAlgorithm::Xxh128);
  std::uint64_t bytes = 0;
  StoredEntryInfo directory;
  try {
    directory = reader_->streamStored(*file->second, layout_.expected.at(name).maxBytes, [&](std::span<const std::uint8_t> chunk) {
      digest.update(chunk);
      bytes += chunk.size();
    });
  } catch (const JobReadError&) {
    return false;  // read the usual way, which reports it
  }
  const std::string hex = digest.hex();
  if (record) {
    first.storedXxh128 = hex, first.storedBytes = bytes, first.directory = directory;
    return true;
  }
  return hex == first.storedXxh128 && bytes == first.storedBytes && directory.deflated == first.directory.deflated &&
         directory.size == first.directory.size && directory.crc32 == first.directory.crc32;
}

std::optional<Bitmap> Inspector::layerImageOrBlankCopy(int l, std::size_t n, Findings& out, bool& blankCopy) const {
  blankCopy = false;
  const std::string name = profile_.layerFileName(*layout_.materials[n], l, layout_.imageFormat);
  const auto group = repeated_.find(name);
  if (group == repeated_.end()) return layerImage(l, n, out);
  RepeatedImage& first = *group->second;
  std::optional<Bitmap> image;
  bool wasFirst = false;
  std::call_once(first.first, [&] {  // the other copies wait for the first one's verdict
    wasFirst = true;
    Findings own = out.sibling();
    image = layerImage(l, n, own);
    DecodedMoments moments;
    if (image) countVoxels(*image, l, moments);
    first.blank = image && own.empty() && moments.count == 0 && storedLike(name, first, true);
    out.merge(own);
  });
  if (wasFirst) return image;
  if (first.blank && storedLike(name, first, false)) {
    blankCopy = true;
    ++filesChecked_, ++blankCopies_;
    return std::nullopt;
  }
  return layerImage(l, n, out);
}

void Inspector::checkLayers() {
  findRepeatedImages();
  const std::size_t materials = layout_.materials.size();
  const std::uint64_t imageBytes = (static_cast<std::uint64_t>(layout_.width) + 7) / 8 * static_cast<std::uint64_t>(layout_.height);
  const std::uint64_t fileCap = layout_.expected.at(profile_.layerFileName(*layout_.materials[0], 0, layout_.imageFormat)).maxBytes;
  const std::uint64_t perLayer = materials * (fileCap + imageBytes);
  const int concurrency = tbb::this_task_arena::max_concurrency();
  const int workers = static_cast<int>(std::clamp<std::uint64_t>(kLayerMemoryBudget / std::max<std::uint64_t>(perLayer, 1), 1,
                                                                 static_cast<std::uint64_t>(concurrency)));
  std::vector<LayerResult> results(static_cast<std::size_t>(layout_.layers), LayerResult(job_.string()));
  const auto checkAll = [&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, layout_.layers, 1), [&](const tbb::blocked_range<int>& range) {
      for (int l = range.begin(); l != range.end(); ++l) {
        common::throwIfInterrupted();  // a job of thousands of layers reads for seconds
        if (decodesLayer(l)) checkLayer(l, results[static_cast<std::size_t>(l)]);
        else readLayerThrough(l, results[static_cast<std::size_t>(l)]);
      }
    });
  };
  // A smaller arena only when the budget needs one: called from the job writer (after its bands ran
  // on the caller's arena), a fresh arena mostly got no worker thread, and every layer was checked on
  // the calling thread (in 3 of 3 runs of classEmit/spring/threads:2, 2 of 4 on the lattice;
  // bench/README.md, "Emit, round 11").
  if (workers >= concurrency) {
    checkAll();
  } else {
    tbb::task_arena arena(workers);
    arena.execute(checkAll);
  }
  std::vector<DecodedMoments> moments(materials);
  std::vector<std::uint64_t> totals(materials, 0);
  for (const LayerResult& r : results) {
    findings_.merge(r.findings);
    for (std::size_t n = 0; n < materials; ++n) {
      totals[n] += r.voxels[n];
      moments[n].merge(r.moments[n]);
    }
  }
  report_.filesChecked = filesChecked_;
  report_.blankCopiesComparedStored = blankCopies_;
  const auto& v = profile_.voxelSizeMm;
  for (std::size_t n = 0; n < materials; ++n) {
    const ProfileMaterial& m = *layout_.materials[n];
    const double ml = static_cast<double>(totals[n]) * v[0] * v[1] * v[2] / 1000.0;
    report_.materials.push_back({m.name, m.role, totals[n], ml, ml * m.densityGPerMl});
  }
  checkStatistics();
  bool everyLayer = true;
  for (int l = 0; l < layout_.layers; ++l) everyLayer = everyLayer && decodesLayer(l);
  checkPart(moments, everyLayer);
  if (everyLayer) checkOrientation(moments);  // the part's position needs every layer
}

bool Inspector::decodesLayer(int l) const {
  return options_.decodeEvery <= 1 || l % options_.decodeEvery == 0 || l == layout_.layers - 1;
}

void Inspector::readLayerThrough(int l, LayerResult& out) const {
  const std::size_t materials = gcvf() ? 1 : layout_.materials.size();
  out.voxels.assign(layout_.materials.size(), 0);
  out.moments.assign(layout_.materials.size(), {});
  const bool zip = reader_->format() == ArchiveFormat::Zip;
  for (std::size_t n = 0; n < materials; ++n) {
    const std::string name = profile_.layerFileName(*layout_.materials[n], l, layout_.imageFormat);
    const auto stored = zip ? options_.storedForms.find(name) : options_.storedForms.end();
    if (stored != options_.storedForms.end()) checkStored(name, stored->second, out.findings);
    else fetch(name, 0, out.findings);
  }
}

// One layer image decoded and checked against the job's size and resolution; nullopt after a finding.
std::optional<Bitmap> Inspector::layerImage(int l, std::size_t n, Findings& out) const {
  const std::string name = profile_.layerFileName(*layout_.materials[n], l, layout_.imageFormat);
  const auto data = fetch(name, UINT64_MAX, out);
  if (!data) return std::nullopt;
  DecodedBitmap decoded;
  try {
    decoded = layout_.imageFormat == ImageFormat::Png ? decodePng1(*data, std::uint64_t(layout_.width) * std::uint64_t(layout_.height))
                                                       : decodeBmp(*data);
  } catch (const ImageError& e) {
    out.at(name, e.what());
    return std::nullopt;
  }
  if (decoded.bitmap.width() != layout_.width || decoded.bitmap.height() != layout_.height) {
    out.at(name, std::to_string(decoded.bitmap.width()) + " x " + std::to_string(decoded.bitmap.height()) +
                     " pixels; the job's images are " + std::to_string(layout_.width) + " x " + std::to_string(layout_.height));
    return std::nullopt;
  }
  const std::uint32_t xPpm = pixelsPerMetre(profile_.xDpi), yPpm = pixelsPerMetre(profile_.yDpi);
  if (decoded.xPixelsPerMetre != xPpm || decoded.yPixelsPerMetre != yPpm) {
    const std::string why = decoded.xPixelsPerMetre == yPpm && decoded.yPixelsPerMetre == xPpm
                                ? " (x and y swapped: the part would print at twice or half its size)"
                                : "";
    out.at(name, "resolution " + std::to_string(decoded.xPixelsPerMetre) + " x " + std::to_string(decoded.yPixelsPerMetre) +
                     " pixels/m; expected " + std::to_string(xPpm) + " x " + std::to_string(yPpm) + " (" +
                     std::to_string(profile_.xDpi) + " x " + std::to_string(profile_.yDpi) + " dpi)" + why);
  }
  return std::move(decoded.bitmap);
}

void Inspector::checkLayer(int l, LayerResult& out) const {
  if (gcvf()) return checkGcvfLayer(l, out);
  const std::size_t materials = layout_.materials.size();
  out.voxels.assign(materials, 0);
  out.moments.assign(materials, {});
  std::vector<std::optional<Bitmap>> bitmaps(materials);
  for (std::size_t n = 0; n < materials; ++n) {
    bool blankCopy = false;
    bitmaps[n] = layerImageOrBlankCopy(l, n, out.findings, blankCopy);
    if (!bitmaps[n] && !blankCopy) continue;
    if (bitmaps[n]) countVoxels(*bitmaps[n], l, out.moments[n]);
    out.voxels[n] = out.moments[n].count;
    const auto& listed = layout_.layerVoxels[static_cast<std::size_t>(l)][n];
    if (listed && *listed != out.voxels[n])
      out.findings.at(profile_.layerFileName(*layout_.materials[n], l, layout_.imageFormat),
                      "has " + std::to_string(out.voxels[n]) + " voxels; the manifest says " + std::to_string(*listed) +
                          " (layers[" + std::to_string(l) + "].voxels." + layout_.materials[n]->name + ")");
  }
  // No voxel may hold two materials: neither two model materials nor support inside the model.
  for (std::size_t a = 0; a < materials; ++a)
    for (std::size_t b = a + 1; b < materials; ++b) {
      if (!bitmaps[a] || !bitmaps[b]) continue;
      if (const std::uint64_t both = countCommonBits(bitmaps[a]->pixelBytes(), bitmaps[b]->pixelBytes()))  // both decoded: one layout
        out.findings.at(profile_.layerFileName(*layout_.materials[a], l, layout_.imageFormat),
                        std::to_string(both) + " voxels hold both " + layout_.materials[a]->name + " and " + layout_.materials[b]->name);
    }
}

// A GrabCAD Voxel Print layer: one RGBA image, each colour a material (nothing else), counts as listed.
void Inspector::checkGcvfLayer(int l, LayerResult& out) const {
  const std::size_t materials = layout_.materials.size();
  out.voxels.assign(materials, 0);
  out.moments.assign(materials, {});
  const std::string name = profile_.layerFileName(*layout_.materials[0], l, layout_.imageFormat);
  const auto data = fetch(name, UINT64_MAX, out.findings);
  if (!data) return;
  GcvfLayerImage image;
  try {
    image = decodeGcvfLayer(*data, profile_, layout_.materials, layout_.width, layout_.height);
  } catch (const ImageError& e) {
    return out.findings.at(name, e.what());
  }
  ++gcvfLayersDecoded_;
  if (image.xPixelsPerMetre != pixelsPerMetre(profile_.xDpi) || image.yPixelsPerMetre != pixelsPerMetre(profile_.yDpi))
    out.findings.at(name, "resolution " + std::to_string(image.xPixelsPerMetre) + " x " + std::to_string(image.yPixelsPerMetre) +
                              " pixels/m; expected " + std::to_string(profile_.xDpi) + " x " + std::to_string(profile_.yDpi) + " dpi");
  if (image.foreignPixels)
    out.findings.at(name, std::to_string(image.foreignPixels) + " pixels have a colour that is not in the material list (first: " +
                              gcvfRgbaText(image.firstForeign) + " at column " + std::to_string(image.firstForeignColumn) +
                              ", row " + std::to_string(image.firstForeignRow) + ")");
  for (std::size_t n = 0; n < materials; ++n) {
    countVoxels(image.bitmaps[n], l, out.moments[n]);
    out.voxels[n] = out.moments[n].count;
    const auto& listed = layout_.layerVoxels[static_cast<std::size_t>(l)][n];
    if (listed && *listed != out.voxels[n])
      out.findings.at(name, "has " + std::to_string(out.voxels[n]) + " " + layout_.materials[n]->name + " voxels; the manifest says " +
                                std::to_string(*listed) + " (layers[" + std::to_string(l) + "].voxels." + layout_.materials[n]->name + ")");
  }
}

void Inspector::checkGcvfConfig() {
  const std::string& name = profile_.buildFileName;
  const auto data = fetch(name, UINT64_MAX, findings_);
  if (!data) return;
  // VoxelCount is checked against the images only when every one was read (else the layers are the defect).
  const bool counted = gcvfLayersDecoded_ == layout_.layers;
  for (const std::string& problem : printer_profiles::checkGcvfConfig(*data, profile_, layout_.width, layout_.height, layout_.layers,
                                                                      report_.materials, counted))
    findings_.at(name, problem);
}

// Word by word, skipping empty words (layers are mostly empty), one moments entry per row: the sums
// are of integers, exact in any order.
void Inspector::countVoxels(const Bitmap& b, int l, DecodedMoments& moments) const {
  const std::size_t stride = b.stride();
  for (int r = 0; r < b.height(); ++r) {
    const std::uint8_t* row = b.row(r);
    std::int64_t count = 0, sumI = 0;
    int iMin = INT32_MAX, iMax = INT32_MIN;
    for (std::size_t at = 0; at < stride; at += 8) {
      std::uint64_t word = 0;
      const std::size_t end = std::min(stride, at + 8);
      std::memcpy(&word, row + at, end - at);
      if (!word) continue;
      for (std::size_t byte = at; byte < end; ++byte) {
        const std::uint8_t bits = row[byte];
        if (!bits) continue;
        const int i0 = layout_.firstColumnI + static_cast<int>(byte) * 8;
        const int n = kBitCounts[bits];
        count += n;
        sumI += static_cast<std::int64_t>(n) * i0 + kBitPositionSums[bits];
        iMin = std::min(iMin, i0 + std::countl_zero(bits));
        iMax = std::max(iMax, i0 + 7 - std::countr_zero(bits));
      }
    }
    if (count) moments.add(layout_.topRowJ - r, layout_.firstLayerK + l, static_cast<int>(count), static_cast<double>(sumI), iMin, iMax);
  }
}

// The images mapped back through the frame must land where the manifest says the part is (computed
// from the grid by the writer): otherwise they are mirrored, flipped or shifted.
void Inspector::checkOrientation(const std::vector<DecodedMoments>& moments) {
  const auto& v = profile_.voxelSizeMm;
  const auto& o = layout_.originMm;
  const auto toMm = [&](const std::array<double, 3>& ijk) {
    return std::array<double, 3>{o[0] + ijk[0] * v[0], o[1] + ijk[1] * v[1], o[2] + ijk[2] * v[2]};
  };
  for (std::size_t n = 0; n < layout_.materials.size(); ++n) {
    const auto& record = layout_.orientation[n];
    const DecodedMoments& mo = moments[n];
    if (!record) continue;
    // The record's count must be the images' (a lie in it hid flipped images: a hostile-input review).
    if (record->voxels != mo.count) {
      findings_.whole(layout_.materials[n]->name + ": the manifest's orientation check counts " + std::to_string(record->voxels) +
                      " voxels, the images hold " + std::to_string(mo.count) + "; the part's position could not be checked");
      continue;
    }
    if (!mo.count) continue;
    const double c = static_cast<double>(mo.count);
    const std::array<double, 3> got[3] = {toMm({1.0 * mo.min[0], 1.0 * mo.min[1], 1.0 * mo.min[2]}),
                                          toMm({1.0 * mo.max[0], 1.0 * mo.max[1], 1.0 * mo.max[2]}),
                                          toMm({mo.sum[0] / c, mo.sum[1] / c, mo.sum[2] / c})};
    const std::array<double, 3> want[3] = {record->minMm, record->maxMm, record->centroidMm};
    const char* what[3] = {"min", "max", "centroid"};
    for (int q = 0; q < 3; ++q) {
      bool same = true;
      for (int a = 0; a < 3; ++a) same = same && std::abs(want[q][a] - got[q][a]) <= 1e-6 * std::max(1.0, std::abs(want[q][a]));
      if (same) continue;
      findings_.whole(layout_.materials[n]->name + ": the images put the " + what[q] + " of the part at " + fmt3(got[q]) +
                      " mm, the manifest at " + fmt3(want[q]) + " mm: the images are mirrored, flipped or shifted against the design");
      break;
    }
  }
}

}  // namespace rodfab::printer_profiles::detail
