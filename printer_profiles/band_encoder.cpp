#include "printer_profiles/band_encoder.hpp"

#include "common/file_hasher.hpp"
#include "common/interrupt.hpp"
#include "common/xxh128.hpp"

#include "printer_profiles/deflate.hpp"
#include "printer_profiles/gcvf_writer.hpp"
#include "printer_profiles/job_staging.hpp"
#include "printer_profiles/leaf_bits.hpp"

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

struct BandEncoder::BandLeaf {
  openvdb::Coord origin;
  LeafRows active, value;
};

// The band's voxels as the layers read them: leaves bucketed by their 8-layer slab (their bytes read
// once per band), and the active tiles above leaf level.
struct BandEncoder::BandVoxels {
  int zBase = 0;
  std::vector<std::vector<BandLeaf>> slabs;
  // collect()'s list of the band's leaves, and each one's slab (kSkipped: nothing to draw, or outside
  // the band) and then its place in the slab.
  static constexpr std::uint32_t kSkipped = UINT32_MAX;
  std::vector<const openvdb::BoolTree::LeafNodeType*> leaves;
  std::vector<std::uint32_t> slabOf, placeIn;
  std::vector<std::pair<openvdb::CoordBBox, bool>> tiles;
  const std::vector<BandLeaf>& slab(int k) const { return slabs[static_cast<std::size_t>((k - zBase) / 8)]; }
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

}  // namespace

BandEncoder::BandEncoder(const BandEncoderSetup& setup)
    : s_(setup), voxels_(std::make_unique<BandVoxels>()), stagedFile_(setup.stagingRoot / "layers.bin") {}

BandEncoder::~BandEncoder() = default;

// Into voxels_, whose vectors keep their capacity from band to band (slabs past this band's stay empty).
// False as soon as an active voxel or tile lies outside `allowed`. A leaf wholly inside passes by its
// origin alone; only leaves at the box's faces are scanned voxel by voxel. (A pass of its own over the
// leaves, before this one, took the lattice 0.06 s a job on one core.) Only the leaves' pointers are
// listed on the calling thread (the tree's internal nodes hold them); the leaves themselves are read on
// the band's TBB workers: their bounds and slabs, then their bits transposed into rows. Listed by a leaf
// iterator that read each leaf's origin, serially, that was about 60 ms of the lattice's job with the
// other core idle (bench/README.md, "Emit, round 11"). A slab keeps the tree's order, as before (the
// layers OR the leaves' bits and sum their moments as integers, so the order shows nowhere anyway).
bool BandEncoder::collect(const LayerBand& band, const openvdb::CoordBBox& allowed) {
  BandVoxels& v = *voxels_;
  v.zBase = band.kBegin & ~7;
  const auto slabs = static_cast<std::size_t>((band.kEnd - 1 - v.zBase) / 8 + 1);
  if (v.slabs.size() < slabs) v.slabs.resize(slabs);
  v.leaves.clear();
  band.material->tree().getNodes(v.leaves);
  v.slabOf.resize(v.leaves.size());
  v.placeIn.resize(v.leaves.size());
  std::atomic<bool> outside{false};
  constexpr std::size_t kGrain = 2048;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, v.leaves.size(), kGrain), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t n = range.begin(); n != range.end(); ++n) {
      const openvdb::BoolTree::LeafNodeType& leaf = *v.leaves[n];
      v.slabOf[n] = BandVoxels::kSkipped;
      if (!allowed.isInside(openvdb::CoordBBox::createCube(leaf.origin(), openvdb::BoolTree::LeafNodeType::DIM))) {
        openvdb::CoordBBox active;
        leaf.evalActiveBoundingBox(active);
        if (active.empty()) continue;  // nothing to draw, and its slab may lie outside the band
        if (!allowed.isInside(active)) {
          outside = true;
          continue;
        }
      }
      v.slabOf[n] = static_cast<std::uint32_t>((leaf.origin().z() - v.zBase) / 8);
    }
  });
  if (outside) return false;
  std::vector<std::uint32_t> counts(v.slabs.size(), 0);
  for (std::size_t n = 0; n < v.leaves.size(); ++n)
    if (v.slabOf[n] != BandVoxels::kSkipped) v.placeIn[n] = counts[v.slabOf[n]]++;
  for (std::size_t s = 0; s < v.slabs.size(); ++s) v.slabs[s].resize(counts[s]);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, v.leaves.size(), kGrain), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t n = range.begin(); n != range.end(); ++n) {
      if (v.slabOf[n] == BandVoxels::kSkipped) continue;
      const openvdb::BoolTree::LeafNodeType& leaf = *v.leaves[n];
      v.slabs[v.slabOf[n]][v.placeIn[n]] = {leaf.origin(), LeafRows(maskBytes(leaf.getValueMask())), LeafRows(boolValueBytes(leaf))};
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

void BandEncoder::rasterize(int k, const BandVoxels& voxels, LayerBitmaps& b, LayerRecord& record) const {
  const JobGeometry& g = s_.form.geometry;
  clearModel(b, g, s_.profile);
  LayerBitmaps::Writer out = b.writer();
  // Read once, not through `g` in the loop (a byte stored may alias anything: LayerBitmaps::Writer).
  const int topRowJ = g.topRowJ, firstColumnI = g.firstColumnI;
  std::array<Moments, 2> moments;
  for (const BandLeaf& leaf : voxels.slab(k)) {
    const std::uint64_t active = leaf.active.layer(k - leaf.origin.z());
    if (!active) continue;
    const std::uint64_t value = leaf.value.layer(k - leaf.origin.z());
    const std::uint64_t rigidRows = active & value, rubberyRows = active & ~value;
    moments[0].addRows(rigidRows, leaf.origin.x(), leaf.origin.y(), k);
    moments[1].addRows(rubberyRows, leaf.origin.x(), leaf.origin.y(), k);
    const auto byte = static_cast<std::size_t>((leaf.origin.x() - firstColumnI) / 8);
    const int firstRow = topRowJ - leaf.origin.y();  // row y of the leaf is image row firstRow - y
    for (int y = 0; y < 8; ++y)
      if ((active >> (8 * y)) & 0xffu)
        out.orByte(firstRow - y, byte, static_cast<std::uint8_t>(rigidRows >> (8 * y)), static_cast<std::uint8_t>(rubberyRows >> (8 * y)));
  }
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
  for (const ProfileMaterial* m : s_.form.emitted) {
    const Bitmap& bitmap = m->role == MaterialRole::Rigid ? b.rigid() : m->role == MaterialRole::Rubbery ? b.rubbery() : b.support;
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
    Bytes form = layerStorage() == ZipStorage::Deflate ? deflateBytes(image, kLayerDeflateLevel, DeflateWrapper::Raw)
                 : owned                                ? std::move(*owned)
                                                        : Bytes(image.begin(), image.end());
    z.length = form.size();
    z.xxh128 = common::xxh128Hex(form);  // lets the verification read the zip's bytes back without inflating them
    record.zipped.push_back(std::move(z));
    zipForms->push_back(std::move(form));
  }
  record.files.push_back(std::move(f));
}

}  // namespace rodfab::printer_profiles
