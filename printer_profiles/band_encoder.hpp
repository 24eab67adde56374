// Internal to printer_profiles/: a band of layers from the material grid to the job's layer images.
// Per layer: the material bitmaps (from the grid's leaf masks), support, voxel counts and moments,
// the previews' share, and the images encoded (BMP, 1-bit PNG or GrabCAD RGBA), hashed for the
// manifest and, for zip jobs, deflated with their zip CRC-32 and kept for the zip: in memory up to a
// budget, then in the job's one staged file.
#pragma once

#include "printer_profiles/job_manifest.hpp"
#include "printer_profiles/job_writer.hpp"
#include "printer_profiles/previews.hpp"

#include <array>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

// What the encoder needs to know of the job; all of it fixed for the job's life.
struct BandEncoderSetup {
  const Profile& profile;
  LayerImageForm form;
  const ColumnTops* supportTops;                        // SupportPolicy::Explicit only
  bool zip;                                             // stage zip forms (else write the files)
  std::filesystem::path filesDir, stagingRoot;          // where files, and zip jobs' staged layers, go
  std::uint64_t zipFormsInMemory = 0;                   // JobOptions::zipFormsInMemory
};

class BandEncoder {
public:
  explicit BandEncoder(const BandEncoderSetup& setup);
  ~BandEncoder();
  BandEncoder(const BandEncoder&) = delete;
  BandEncoder& operator=(const BandEncoder&) = delete;

  // Layers [band.kBegin, band.kEnd) on the caller's TBB arena: fills their records in `layers`
  // (indexed by layer) and adds them to `previews`. The bytes depend on each layer alone. Returns false,
  // having touched neither `layers` nor `previews`, when an active voxel or tile of the band's grid lies
  // outside `allowed` (checked in the same pass over the grid's leaves that gathers them).
  [[nodiscard]] bool encode(const LayerBand& band, const openvdb::CoordBBox& allowed, std::vector<LayerRecord>& layers,
                            Previews& previews);

  // Zip jobs: the file the zip forms not kept in memory are staged in (writeZip's `stagedFile`), and
  // closing it, checked, once every band is encoded and before the zip is built from it; throws naming
  // the file when its last bytes cannot be written.
  const std::filesystem::path& stagedFile() const { return stagedFile_; }
  void finishStaging();

  // How the layer images go into the zip: PNG as it is (already compressed), BMP deflated (but stored
  // when deflate would not shrink it: LayerRecord::zipped says for each image).
  ZipStorage layerStorage() const { return s_.form.imageFormat == ImageFormat::Png ? ZipStorage::Store : ZipStorage::Deflate; }

private:
  struct LeafLayer;
  struct BandVoxels;
  bool collect(const LayerBand& band, const openvdb::CoordBBox& allowed);  // into voxels_; false: outside `allowed`
  void rasterize(int k, const BandVoxels& voxels, LayerBitmaps& b, LayerRecord& record) const;
  // A layer's leaf records into its bitmaps (rows from topRowJ down, columns from firstColumnI) and moments.
  static void drawLeaves(std::span<const LeafLayer> leaves, LayerBitmaps::Writer out, int topRowJ, int firstColumnI, int k,
                         std::array<Moments, 2>& moments);
  void addSupport(int layer, LayerBitmaps& b) const;
  void encodeImages(int layer, const LayerBitmaps& b, LayerRecord& record, std::vector<Bytes>* zipForms) const;
  // An image's checksums as the job records them: XXH3-128 (manifest), CRC-32 (zip directory; zip jobs only).
  struct ImageSums {
    std::string xxh128;
    std::uint32_t crc32 = 0;
  };
  static ImageSums sumsOf(std::span<const std::uint8_t> image, bool zip);
  void keepImage(const ProfileMaterial& m, int layer, std::span<const std::uint8_t> image, ImageSums sums, LayerRecord& record,
                 std::vector<Bytes>* zipForms, Bytes* owned = nullptr) const;
  // A material's image of a layer without a voxel of it: the same bytes in every such layer (the
  // profile's headers and the background), so its checksums and zip form are made once a job and
  // shared. A tray whose parts lie far apart in z has thousands of them, each hashed and deflated at
  // up to several MB before. False when `bitmap` is not that image (it is compared whole first).
  struct BlankImage;
  bool keepBlank(std::size_t material, const Bitmap& bitmap, int layer, LayerRecord& record, std::vector<Bytes>* zipForms) const;
  const BlankImage& blankImage(std::size_t material, const Bitmap& bitmap) const;
  void stageBand(int firstLayer, std::vector<std::vector<Bytes>>& zipForms, std::vector<LayerRecord>& layers);
  bool gcvf() const { return s_.profile.jobFormat == JobFormat::Gcvf; }

  BandEncoderSetup s_;
  // The band's bitmaps, kept from band to band: cleared, not reallocated (fresh pages cost a fault each).
  std::vector<LayerBitmaps> bitmaps_;
  // The band's leaves and tiles as rasterize reads them, likewise kept: collected into fresh vectors,
  // a band of the dense block cost 9 to 13 MB of new pages (page faults and clearing: 6 % of the
  // dense block's CPU samples, as much as deflate).
  std::unique_ptr<BandVoxels> voxels_;
  // The emitted materials' blank images (keepBlank), made by the first blank layer of each; they
  // outlive the records' StagedZipData that point into them, as kept_ does.
  mutable std::mutex blankMutex_;
  mutable std::vector<std::unique_ptr<const BlankImage>> blank_;
  // Zip jobs: the zip forms kept in memory (up to s_.zipFormsInMemory bytes), then every further one
  // after another in one staged file, created when the first one goes there. The records'
  // StagedZipData point into kept_ until the job is written.
  std::deque<Bytes> kept_;
  std::uint64_t keptBytes_ = 0;
  std::filesystem::path stagedFile_;
  std::ofstream staged_;
  std::uint64_t stagedBytes_ = 0;
};

}  // namespace rodfab::printer_profiles
