#include "printer_profiles/band_encoder.hpp"

#include "common/file_hasher.hpp"
#include "common/interrupt.hpp"
#include "common/xxh128.hpp"

#include "printer_profiles/deflate.hpp"
#include "printer_profiles/gcvf_writer.hpp"
#include "printer_profiles/job_staging.hpp"
#include "printer_profiles/leaf_bits.hpp"
#include "printer_profiles/popcount_clones.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;

// One leaf's voxels in one layer of the band, as that layer's images take them: the leaf's origin and its
// 8 rows of rigid and of rubbery pixels (row y of the leaf in byte y, x = 0 in bit 7 of each byte).
struct BandEncoder::LeafLayer {
  std::int32_t x = 0, y = 0;
  std::uint64_t rigid = 0, rubbery = 0;
};

// The band's voxels as the layers read them: every leaf's rows per layer it has voxels in, layer by
// layer (each layer reads its own records, one after another, and no leaf without voxels there), and
// the active tiles above leaf level.
struct BandEncoder::BandVoxels {
  int kBegin = 0;
  std::vector<LeafLayer> records;         // layer n's at [layerStart[n], layerStart[n + 1])
  std::vector<std::size_t> layerStart;    // the band's layers + 1
  // collect()'s list of the band's leaves; per leaf, the layers of its 8 it has voxels in (bit z: layer
  // origin.z + z; 0: nothing to draw, or outside the band); per chunk of leaves, where its records
  // start in each layer.
  std::vector<const openvdb::BoolTree::LeafNodeType*> leaves;
  std::vector<std::uint8_t> layersOf;
  std::vector<std::size_t> chunkStart;    // chunk c, layer n at [c * layers + n]
  std::vector<std::pair<openvdb::CoordBBox, bool>> tiles;
  std::span<const LeafLayer> layer(int k) const {
    const auto n = static_cast<std::size_t>(k - kBegin);
    return {records.data() + layerStart[n], layerStart[n + 1] - layerStart[n]};
  }
};

namespace {

// A layer bitmap of the job: held in the memory of its BMP file, so that a BMP job's image is the
// bitmap itself (no row copied: Bitmap::inBmpFile); PNG and RGBA images read its rows like any other's.
Bitmap layerBitmap(const JobGeometry& g, const Profile& profile) { return Bitmap::inBmpFile(g.width, g.height, profile.xDpi, profile.yDpi); }

// Empties the layer's bitmaps for this layer: only the words the last layer wrote are cleared when they
// have the job's size (mostly empty layers then cost next to nothing to clear).
void clearModel(LayerBitmaps& b, const JobGeometry& g, const Profile& profile) {
  if (b.rigid().width() == g.width && b.rigid().height() == g.height) b.clear();
  else b = LayerBitmaps(g.width, g.height, profile.xDpi, profile.yDpi);
}

// Which of a leaf's 8 layers (bit z: its layer z) hold active voxels: the OR of its columns' bytes.
std::uint8_t layersWithVoxels(const openvdb::BoolTree::LeafNodeType& leaf) {
  std::uint64_t any = 0;
  for (openvdb::Index n = 0; n < 8; ++n) any |= leaf.getValueMask().template getWord<openvdb::Index64>(n);
  any |= any >> 32;
  any |= any >> 16;
  any |= any >> 8;
  return static_cast<std::uint8_t>(any);
}

// Calls fn(chunk, first, end) for the chunks of kChunk leaves of `leaves` (the last may be short), on
// the caller's TBB arena. The chunks are fixed by the count alone, so what is made per chunk is too.
constexpr std::size_t kChunk = 512;
template <typename Fn>
void forEachChunk(std::size_t leaves, Fn&& fn) {
  const std::size_t chunks = (leaves + kChunk - 1) / kChunk;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t c = range.begin(); c != range.end(); ++c) fn(c, c * kChunk, std::min(leaves, (c + 1) * kChunk));
  });
}

}  // namespace

BandEncoder::BandEncoder(const BandEncoderSetup& setup)
    : s_(setup), voxels_(std::make_unique<BandVoxels>()), stagedFile_(setup.stagingRoot / "layers.bin") {}

BandEncoder::~BandEncoder() = default;

// Into voxels_, whose vectors keep their capacity from band to band. False as soon as an active voxel
// or tile lies outside `allowed`. A leaf wholly inside passes by its origin alone; only leaves at the
// box's faces are scanned voxel by voxel. (A pass of its own over the leaves, before this one, took the
// lattice 0.06 s a job on one core.) Only the leaves' pointers are listed on the calling thread (the
// tree's internal nodes hold them); the leaves are read on the band's TBB workers, by fixed chunks:
// first their bounds and the layers they have voxels in (counted per chunk and layer), then, once the
// counts say where each chunk's records go in each layer, their bits transposed into rows, a record
// for each layer the leaf has voxels in. (Before, every layer went through all of its slab's leaves,
// 140 bytes each with the rows of all 8 layers, skipping those with nothing in it: README.md, "Emit,
// round 12".) The records keep the tree's order within a layer (the layers OR the leaves' bits and sum
// integer moments, so no order would show anyway).
bool BandEncoder::collect(const LayerBand& band, const openvdb::CoordBBox& allowed) {
  BandVoxels& v = *voxels_;
  const auto layers = static_cast<std::size_t>(band.kEnd - band.kBegin);
  v.kBegin = band.kBegin;
  v.leaves.clear();
  band.material->tree().getNodes(v.leaves);
  v.layersOf.resize(v.leaves.size());
  std::vector<std::size_t>& start = v.chunkStart;
  start.assign((v.leaves.size() + kChunk - 1) / kChunk * layers, 0);
  const auto layerOf = [&](const openvdb::BoolTree::LeafNodeType& leaf, int z) {
    return static_cast<std::size_t>(leaf.origin().z() + z - band.kBegin);
  };
  std::atomic<bool> outside{false};
  forEachChunk(v.leaves.size(), [&](std::size_t chunk, std::size_t first, std::size_t end) {
    std::size_t* counts = start.data() + chunk * layers;
    for (std::size_t n = first; n != end; ++n) {
      const openvdb::BoolTree::LeafNodeType& leaf = *v.leaves[n];
      v.layersOf[n] = 0;
      if (!allowed.isInside(openvdb::CoordBBox::createCube(leaf.origin(), openvdb::BoolTree::LeafNodeType::DIM))) {
        openvdb::CoordBBox active;
        leaf.evalActiveBoundingBox(active);
        if (active.empty()) continue;  // nothing to draw, and its layers may lie outside the band
        if (!allowed.isInside(active)) {
          outside = true;
          continue;
        }
      }
      v.layersOf[n] = layersWithVoxels(leaf);
      for (unsigned z = v.layersOf[n]; z; z &= z - 1) ++counts[layerOf(leaf, std::countr_zero(z))];
    }
  });
  if (outside) return false;
  // Layer by layer, each chunk's records after the previous chunk's: `start` turns from counts into places.
  v.layerStart.resize(layers + 1);
  std::size_t total = 0;
  for (std::size_t n = 0; n < layers; ++n) {
    v.layerStart[n] = total;
    for (std::size_t at = n; at < start.size(); at += layers) total += std::exchange(start[at], total);
  }
  v.layerStart[layers] = total;
  v.records.resize(total);
  forEachChunk(v.leaves.size(), [&](std::size_t chunk, std::size_t first, std::size_t end) {
    std::size_t* next = start.data() + chunk * layers;
    for (std::size_t n = first; n != end; ++n) {
      if (!v.layersOf[n]) continue;
      const openvdb::BoolTree::LeafNodeType& leaf = *v.leaves[n];
      const LeafRows active(maskBytes(leaf.getValueMask())), value(boolValueBytes(leaf));
      for (unsigned z = v.layersOf[n]; z; z &= z - 1) {
        const int at = std::countr_zero(z);
        const std::uint64_t rows = active.layer(at), rigid = value.layer(at);
        v.records[next[layerOf(leaf, at)]++] = {leaf.origin().x(), leaf.origin().y(), rows & rigid, rows & ~rigid};
      }
    }
  });
  v.tiles.clear();
  bool inside = true;
  forEachActiveTile(band.material->tree(), [&](const openvdb::CoordBBox& box, bool value) {
    inside = inside && allowed.isInside(box);
    v.tiles.emplace_back(box, value);
  });
  return inside;
}

bool BandEncoder::encode(const LayerBand& band, const openvdb::CoordBBox& allowed, std::vector<LayerRecord>& layers, Previews& previews) {
  const int firstLayer = s_.form.geometry.layer(band.kBegin);
  const int count = band.kEnd - band.kBegin;
  if (!collect(band, allowed)) return false;
  const BandVoxels& voxels = *voxels_;
  bitmaps_.resize(static_cast<std::size_t>(count));
  // Zip jobs keep each image's zip form (deflated BMP, or the PNG as it is) in memory until the band
  // is staged in one file: staging thousands of files costs more in the file system than compressing.
  std::vector<std::vector<Bytes>> zipForms(s_.zip ? static_cast<std::size_t>(count) : 0);
  const openvdb::FloatGrid* modulus = band.modulus.get();
  tbb::parallel_for(tbb::blocked_range<int>(0, count, 1), [&](const tbb::blocked_range<int>& range) {
    for (int n = range.begin(); n != range.end(); ++n) {
      common::throwIfInterrupted();  // a band of large layers takes seconds
      const int k = band.kBegin + n, layer = firstLayer + n;
      LayerBitmaps& b = bitmaps_[static_cast<std::size_t>(n)];
      LayerRecord& record = layers[static_cast<std::size_t>(layer)];
      rasterize(k, voxels, b, record);
      if (s_.form.support == SupportPolicy::Explicit) addSupport(layer, b);
      // The model's pixels as rasterize counted them into the moments: each leaf and tile covers pixels
      // no other one does (a grid's leaves and tiles are disjoint), so the sums are the bitmaps' counts
      // without a pass over them (the verification and inspect count the decoded images independently).
      record.voxels = {record.moments[0].count, record.moments[1].count, b.hasSupport ? b.support.count() : 0};
      previews.addLayer(layer, b, modulus);
      encodeImages(layer, b, record, s_.zip ? &zipForms[static_cast<std::size_t>(n)] : nullptr);
    }
  });
  previews.addTopLayers(firstLayer, bitmaps_, modulus);
  if (s_.zip) stageBand(firstLayer, zipForms, layers);
  return true;
}

// The band's zip forms kept in memory while the job's add up to at most s_.zipFormsInMemory, and past that
// appended to the job's one staged file, the layers' one after another. Kept, they are not copied into
// the page cache and read back out of it when the zip is built (on the spring, 40 MB: stageBand and the
// staged reads were 0.1 s of CPU); the budget bounds the memory they take. One file for the job, not
// one a band: creating a file cost an ext4 inode allocation each (find_inode_bit, 1.5 % of the
// spring's samples), and the zip's builder opened it once an entry. Each entry's bytes depend on its
// image alone, so neither the band size nor where it was kept shows in the job.
void BandEncoder::stageBand(int firstLayer, std::vector<std::vector<Bytes>>& zipForms, std::vector<LayerRecord>& layers) {
  bool wrote = false;
  for (std::size_t n = 0; n < zipForms.size(); ++n) {
    LayerRecord& record = layers[static_cast<std::size_t>(firstLayer) + n];
    for (std::size_t f = 0; f < zipForms[n].size(); ++f) {
      Bytes& data = zipForms[n][f];
      StagedZipData& z = record.zipped[f];
      if (z.inMemory) continue;  // a blank image's shared form (keepBlank)
      if (keptBytes_ + data.size() <= s_.zipFormsInMemory) {
        keptBytes_ += data.size();
        z.memory = kept_.emplace_back(std::move(data));
        z.inMemory = true;
        continue;
      }
      if (!staged_.is_open()) staged_.open(stagedFile_, std::ios::binary | std::ios::trunc);
      staged_.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
      z.offset = stagedBytes_;
      stagedBytes_ += data.size();
      wrote = true;
    }
  }
  if (!wrote) return;
  staged_.flush();  // the zip is built from the file through other handles
  if (!staged_) throw std::runtime_error(stagedFile_.string() + ": cannot write (disk full or no permission?)");
}

void BandEncoder::finishStaging() {
  if (!staged_.is_open()) return;
  staged_.close();  // a failed close (the last bytes not written) sets failbit
  if (!staged_) throw std::runtime_error(stagedFile_.string() + ": cannot write (disk full or no permission?)");
}

// Cloned for CPUs with a popcount instruction, which Moments::addRows counts with (nothing here throws),
// and flattened: left to itself GCC called the baseline addRows for one of the two sums, a libgcc call
// per popcount. The writer and the sums are this function's own: a byte stored through a uint8_t
// pointer may alias anything whose address is known outside, and the caller's would be read and
// written back around every store.
[[gnu::flatten]] RODFAB_POPCNT_CLONES void BandEncoder::drawLeaves(std::span<const LeafLayer> leaves, LayerBitmaps::Writer out,
                                                                    int topRowJ, int firstColumnI, int k, std::array<Moments, 2>& moments) {
  for (const LeafLayer& leaf : leaves)
    out.orLeafRows(topRowJ - leaf.y, static_cast<std::size_t>((leaf.x - firstColumnI) / 8), leaf.rigid, leaf.rubbery);
  Moments rigid, rubbery;  // in a loop of their own: with the writer's, their 20 sums did not fit in registers
  for (const LeafLayer& leaf : leaves) {
    rigid.addRows(leaf.rigid, leaf.x, leaf.y, k);
    rubbery.addRows(leaf.rubbery, leaf.x, leaf.y, k);
  }
  moments[0].merge(rigid);
  moments[1].merge(rubbery);
}

void BandEncoder::rasterize(int k, const BandVoxels& voxels, LayerBitmaps& b, LayerRecord& record) const {
  const JobGeometry& g = s_.form.geometry;
  clearModel(b, g, s_.profile);
  LayerBitmaps::Writer out = b.writer();
  // Read once, not through `g` in the loop (a byte stored may alias anything: LayerBitmaps::Writer).
  const int topRowJ = g.topRowJ, firstColumnI = g.firstColumnI;
  std::array<Moments, 2> moments;
  drawLeaves(voxels.layer(k), out, topRowJ, firstColumnI, k, moments);
  for (const auto& [box, value] : voxels.tiles) {
    if (k < box.min().z() || k > box.max().z()) continue;
    for (int j = box.min().y(); j <= box.max().y(); ++j)
      for (int i = box.min().x(); i <= box.max().x(); i += 8) {  // tiles are 8-aligned in x
        out.orByte(g.row(j), static_cast<std::size_t>(g.column(i) / 8), value ? 0xff : 0, value ? 0 : 0xff);
        moments[value ? 0 : 1].add(0xff, i, j, k);
      }
  }
  record.moments = moments;
}

// Support fills each column from the tray up to its highest model voxel, wherever the model is not.
void BandEncoder::addSupport(int layer, LayerBitmaps& b) const {
  const ColumnTops& tops = *s_.supportTops;
  if (b.support.width() == s_.form.geometry.width && b.support.height() == s_.form.geometry.height) b.support.clear();
  else b.support = layerBitmap(s_.form.geometry, s_.profile);
  b.hasSupport = true;
  for (int r = 0; r < s_.form.geometry.height; ++r) {
    if (tops.rowMaximum()[static_cast<std::size_t>(r)] <= layer) continue;
    std::uint8_t* out = b.support.row(r);
    const std::uint8_t* rigid = b.rigid().row(r);
    const std::uint8_t* rubbery = b.rubbery().row(r);
    for (std::size_t byte = 0; byte < b.support.stride(); ++byte) {
      std::uint8_t above = 0;
      for (int bit = 0; bit < 8; ++bit)
        if (tops.top(static_cast<int>(byte) * 8 + bit, r) > layer) above = static_cast<std::uint8_t>(above | (0x80u >> bit));
      out[byte] = static_cast<std::uint8_t>(above & ~(rigid[byte] | rubbery[byte]));
    }
  }
}

// Encodes the layer's images; writes them to the staging folder, or hands their zip forms to
// `zipForms` (deflated BMP, PNG as it is) and records their sizes and CRCs in record.zipped.
void BandEncoder::encodeImages(int layer, const LayerBitmaps& b, LayerRecord& record, std::vector<Bytes>* zipForms) const {
  record.files.clear();
  record.zipped.clear();
  if (gcvf()) {  // one RGBA image holds every material of the layer
    Bytes rgba = encodeGcvfLayer(b.rigid(), b.rubbery(), s_.profile);
    keepImage(*s_.form.emitted[0], layer, rgba, sumsOf(rgba, zipForms != nullptr), record, zipForms, &rgba);
    return;
  }
  for (std::size_t i = 0; i < s_.form.emitted.size(); ++i) {
    const ProfileMaterial* m = s_.form.emitted[i];
    const Bitmap& bitmap = m->role == MaterialRole::Rigid ? b.rigid() : m->role == MaterialRole::Rubbery ? b.rubbery() : b.support;
    if (record.voxels[static_cast<std::size_t>(m->role)] == 0 && keepBlank(i, bitmap, layer, record, zipForms)) continue;
    if (s_.form.imageFormat == ImageFormat::Png) {
      Bytes png = encodePng1(bitmap, s_.profile.xDpi, s_.profile.yDpi);
      keepImage(*m, layer, png, sumsOf(png, zipForms != nullptr), record, zipForms, &png);
      continue;
    }
    // The bitmap's memory is its BMP file (layerBitmap): checksummed and deflated as it lies.
    const std::span<const std::uint8_t> bmp = bitmap.bmpFile();
    if (bmp.empty()) throw std::logic_error("encodeImages: a layer bitmap not made by layerBitmap");
    keepImage(*m, layer, bmp, sumsOf(bmp, zipForms != nullptr), record, zipForms);
  }
}

struct BandEncoder::BlankImage {
  Bytes bitmap;               // the bitmap's memory (its BMP file) the image was made from
  Bytes png;                  // PNG jobs: the image file; BMP jobs: empty (the file is `bitmap`)
  ImageSums sums;             // of the image file
  Bytes zipForm;              // zip jobs: the image file deflated (BMP) or as it is (PNG)
  std::string zipFormXxh128;  // of zipForm
  std::span<const std::uint8_t> file() const { return png.empty() ? std::span<const std::uint8_t>(bitmap) : png; }
};

namespace {

// Where a BMP file's pixels start (its header's bfOffBits); 0 when `bmp` is too short to say or says
// more than its size.
std::size_t bmpPixelOffset(std::span<const std::uint8_t> bmp) {
  if (bmp.size() < 14) return 0;
  const std::size_t offset = bmp[10] | std::size_t{bmp[11]} << 8 | std::size_t{bmp[12]} << 16 | std::size_t{bmp[13]} << 24;
  return offset <= bmp.size() ? offset : 0;
}

}  // namespace

// Made under the lock by the first blank layer of the material; later ones only read it.
const BandEncoder::BlankImage& BandEncoder::blankImage(std::size_t material, const Bitmap& bitmap) const {
  const std::lock_guard lock(blankMutex_);
  if (blank_.size() <= material) blank_.resize(s_.form.emitted.size());
  if (!blank_[material]) {
    auto made = std::make_unique<BlankImage>();
    const std::span<const std::uint8_t> bmp = bitmap.bmpFile();
    made->bitmap.assign(bmp.begin(), bmp.end());
    if (s_.form.imageFormat == ImageFormat::Png) made->png = encodePng1(bitmap, s_.profile.xDpi, s_.profile.yDpi);
    made->sums = sumsOf(made->file(), s_.zip);
    if (s_.zip) {
      // Compressed once and stored in every blank layer: by zlib at its smallest (a tenth of igzip's
      // level 0 on a blank image: a sparse tray's job 768 -> 86 MB).
      made->zipForm = layerStorage() == ZipStorage::Deflate ? deflateSmallest(made->file()) : Bytes(made->png.begin(), made->png.end());
      made->zipFormXxh128 = common::xxh128Hex(made->zipForm);
    }
    blank_[material] = std::move(made);
  }
  return *blank_[material];
}

bool BandEncoder::keepBlank(std::size_t material, const Bitmap& bitmap, int layer, LayerRecord& record, std::vector<Bytes>* zipForms) const {
  const std::span<const std::uint8_t> bmp = bitmap.bmpFile();
  if (bmp.empty()) return false;
  // Its pixels are clear: the layer counts none of this material (drawLeaves counts the bits it sets
  // in bitmaps cleared before, support counts its bitmap), so the headers are what is compared. The
  // whole image was compared at first: reading every blank image back cost the sparse tray 40 % of its
  // CPU, as much as the hashing it saved.
  const BlankImage& blank = blankImage(material, bitmap);
  const std::size_t header = bmpPixelOffset(blank.bitmap);
  if (blank.bitmap.size() != bmp.size() || header == 0 || std::memcmp(blank.bitmap.data(), bmp.data(), header) != 0) return false;
  const ProfileMaterial& m = *s_.form.emitted[material];
  FileRecord f{s_.profile.layerFileName(m, layer, s_.form.imageFormat), blank.file().size(), blank.sums.xxh128};
  if (!zipForms) {
    writeFile(s_.filesDir / f.name, blank.file());
  } else {
    StagedZipData z;
    z.size = blank.file().size();
    z.crc32 = blank.sums.crc32;
    z.length = blank.zipForm.size();
    z.xxh128 = blank.zipFormXxh128;
    z.inMemory = true;  // the blank image's own bytes: stageBand neither keeps nor stages a copy
    z.memory = blank.zipForm;
    z.storage = layerStorage();
    record.zipped.push_back(std::move(z));
    zipForms->emplace_back();  // keeps zipForms[f] beside record.zipped[f]
  }
  record.files.push_back(std::move(f));
  return true;
}

// In pieces of 16 KiB (a third of the L1 data cache): XXH3 brings each piece in, the CRC reads it there,
// instead of two passes over the whole image (bench/README.md, "Emit, round 4"). The same digest as
// the one-shot XXH3-128 (common::FileHasher).
BandEncoder::ImageSums BandEncoder::sumsOf(std::span<const std::uint8_t> image, bool zip) {
  constexpr std::size_t kPiece = std::size_t{16} << 10;
  common::FileHasher hasher(common::HashAlgorithm::Xxh128);
  std::uint32_t crc = 0;
  for (std::size_t at = 0; at < image.size(); at += kPiece) {
    const std::span<const std::uint8_t> piece = image.subspan(at, std::min(kPiece, image.size() - at));
    hasher.update(piece);
    if (zip) crc = zipCrc32(piece, crc);
  }
  return {hasher.hex(), crc};
}

// One image of the layer with its checksums: its manifest record (size, XXH3-128), and the file
// written or its zip form kept with its size, CRC-32 and the form's XXH3-128. `owned`, when given,
// holds `image` and may be moved from (a PNG is kept as it is, not copied).
void BandEncoder::keepImage(const ProfileMaterial& m, int layer, std::span<const std::uint8_t> image, ImageSums sums, LayerRecord& record,
                            std::vector<Bytes>* zipForms, Bytes* owned) const {
  FileRecord f{s_.profile.layerFileName(m, layer, s_.form.imageFormat), image.size(), std::move(sums.xxh128)};
  if (!zipForms) {
    writeFile(s_.filesDir / f.name, image);
  } else {
    StagedZipData z;
    z.size = image.size();
    z.crc32 = sums.crc32;
    z.storage = layerStorage();
    Bytes form;
    // A BMP deflated unless deflate would not shrink it (a layer filled with dithered noise), and stored
    // when its deflated form is no smaller: the zip holds the smaller, as zip tools do.
    if (z.storage == ZipStorage::Deflate && !deflateWouldNotShrink(image, kLayerDeflateLevel)) {
      form = deflateBytes(image, kLayerDeflateLevel, DeflateWrapper::Raw);
      if (form.size() >= image.size()) z.storage = ZipStorage::Store;
    } else {
      z.storage = ZipStorage::Store;
    }
    if (z.storage == ZipStorage::Store) form = owned ? std::move(*owned) : Bytes(image.begin(), image.end());
    z.length = form.size();
    z.xxh128 = common::xxh128Hex(form);  // lets the verification read the zip's bytes back without inflating them
    record.zipped.push_back(std::move(z));
    zipForms->push_back(std::move(form));
  }
  record.files.push_back(std::move(f));
}

}  // namespace rodfab::printer_profiles
