// The inspector behind inspectJob (inspect.hpp), shared by inspect.cpp (the job's entries, manifest,
// profile, build file, previews and report) and inspect_layers.cpp (the layer images, decoded and
// counted in parallel, and the part's orientation). Internal to printer_profiles/.
#pragma once

#include "printer_profiles/bitmap.hpp"
#include "printer_profiles/inspect.hpp"
#include "printer_profiles/inspect_layout.hpp"
#include "printer_profiles/job_reader.hpp"
#include "printer_profiles/profile.hpp"

#include <array>
#include <atomic>
#include <climits>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace rodfab::printer_profiles::detail {

namespace fs = std::filesystem;

// Voxel index sums of one material as decoded from the images, to compare with the manifest's.
struct DecodedMoments {
  std::uint64_t count = 0;
  std::array<double, 3> sum{};
  std::array<int, 3> min{INT32_MAX, INT32_MAX, INT32_MAX}, max{INT32_MIN, INT32_MIN, INT32_MIN};
  void add(int j, int k, int n, double sumI, int iMin, int iMax) {
    count += static_cast<std::uint64_t>(n);
    sum[0] += sumI;
    sum[1] += static_cast<double>(n) * j;
    sum[2] += static_cast<double>(n) * k;
    min = {std::min(min[0], iMin), std::min(min[1], j), std::min(min[2], k)};
    max = {std::max(max[0], iMax), std::max(max[1], j), std::max(max[2], k)};
  }
  void merge(const DecodedMoments& o) {
    count += o.count;
    for (int a = 0; a < 3; ++a) {
      sum[a] += o.sum[a];
      min[a] = std::min(min[a], o.min[a]);
      max[a] = std::max(max[a], o.max[a]);
    }
  }
};

struct LayerResult {
  explicit LayerResult(const std::string& job) : findings(job) {}
  Findings findings;
  std::vector<std::uint64_t> voxels;    // per job material
  std::vector<DecodedMoments> moments;  // per job material
};

class Inspector {
public:
  Inspector(const fs::path& job, const InspectOptions& options, InspectReport& report)
      : job_(job), options_(options), report_(report), findings_(job.string()) {}

  void run();

private:
  void finish() { report_.defects = findings_.take(); }
  bool gcvf() const { return profile_.jobFormat == JobFormat::Gcvf; }

  // Names every entry that no job may hold; keeps the safe, unique, regular files for reading.
  void indexEntries();
  std::string tooManyEntries() const;
  const JobEntry* manifestEntry();
  bool readManifest();
  void notCheckedAsTooLarge(const std::string& most);

  // The profile comes from the caller or, by name only, from the bundled ones: never from a path.
  bool resolveProfile();
  bool findProfile();
  bool readJobLayout();
  void checkEntries();

  // Missing entries; a material whose every image is missing is one finding, not one per layer.
  void reportMissing();

  // Streams an expected entry: its declared and actual size against its cap, its size and checksum
  // against the manifest. Keeps at most `keep` leading bytes. nullopt after a finding.
  std::optional<Bytes> fetch(const std::string& name, std::uint64_t keep, Findings& out) const;
  // A zip entry the caller staged (InspectOptions::storedForms): its bytes as stored, not decoded,
  // against their recorded length and XXH3-128; the zip's directory against the method and CRC-32
  // recorded and the manifest's size.
  void checkStored(const std::string& name, const StoredForm& want, Findings& out) const;
  void checkBuildFile();

  // Previews are only looked at by people: their checksum and that they are 8-bit RGB PNGs suffice.
  void checkPreviews();

  // The job report (report.html) is read by people too: its checksum, and that it is an HTML page.
  void checkReport();
  void checkLayers();

  // One layer image decoded and checked against the job's size and resolution; nullopt after a finding.
  std::optional<Bitmap> layerImage(int l, std::size_t n, Findings& out) const;
  // A zip job's layer images whose manifest digest and size repeat (a material's blank image, which
  // the writer deflates once a job and repeats byte for byte): the first copy read is checked and
  // decoded in full; when it was blank and clean, a later copy whose stored bytes and directory record
  // equal it holds the same verified image, so it is read as stored, not inflated and decoded again.
  struct RepeatedImage;
  void findRepeatedImages();
  // layerImage, or nullopt with `blankCopy` set for a stored copy of a checked blank image.
  std::optional<Bitmap> layerImageOrBlankCopy(int l, std::size_t n, Findings& out, bool& blankCopy) const;
  bool storedLike(const std::string& name, RepeatedImage& first, bool record) const;
  void checkLayer(int l, LayerResult& out) const;
  bool decodesLayer(int l) const;
  // A layer that is not decoded: its images read through (sizes and checksums, or their stored forms).
  void readLayerThrough(int l, LayerResult& out) const;

  // A GrabCAD Voxel Print layer: one RGBA image, each colour a material (nothing else), counts as listed.
  void checkGcvfLayer(int l, LayerResult& out) const;
  void checkGcvfConfig();
  void countVoxels(const Bitmap& b, int l, DecodedMoments& moments) const;

  // The images mapped back through the frame must land where the manifest says the part is (computed
  // from the grid by the writer): otherwise they are mirrored, flipped or shifted.
  void checkOrientation(const std::vector<DecodedMoments>& moments);

  // inspect_statistics.cpp: the statistics block against the layers' counts and the profile; the
  // part's box against the frame, its size in mm and (when every layer was decoded) the images.
  std::optional<std::uint64_t> listedVoxels(std::size_t material) const;
  void checkStatistics();
  void checkPart(const std::vector<DecodedMoments>& moments, bool everyLayerDecoded);
  void checkFrameOfPart(const PartRecord& part, const std::array<std::int64_t, 3>& dim);

  fs::path job_;
  const InspectOptions& options_;
  InspectReport& report_;
  Findings findings_;
  std::vector<Profile> candidates_;
  ProfileLimits limits_;
  std::unique_ptr<JobReader> reader_;
  // Without InspectOptions::profile, a listing cut at the bundled profiles' widest limit is a defect only
  // once the manifest names a bundled profile (a profile file's jobs may hold more).
  bool truncatedPastBundled_ = false;
  std::optional<JobEntry> unlistedManifest_;  // the manifest, looked up by name when the listing stopped before it
  std::map<std::string, const JobEntry*> files_;  // safe, unambiguous regular files by name
  std::set<std::string> folders_;                 // safe folder entries ("previews/")
  std::set<std::string> reported_;                // names already found wanting
  Profile profile_;
  JobLayout layout_;
  mutable std::atomic<std::size_t> filesChecked_{0};
  mutable std::atomic<std::size_t> blankCopies_{0};
  mutable std::atomic<int> gcvfLayersDecoded_{0};  // gcvf layer images read without a defect of their own
  std::map<std::string, std::shared_ptr<RepeatedImage>> repeated_;  // layer image name -> its group (findRepeatedImages)
};

}  // namespace rodfab::printer_profiles::detail
