// Internal to printer_profiles/ (used by `inspect`): the complete layout a job must have, derived from its
// printer profile and the few numbers of its manifest that the profile bounds (image size, layer count,
// image format, support policy, previews), with the most bytes each entry may hold; and the manifest read
// as untrusted JSON (size, depth and value count limited before it is built, never re-serialized).
// Defined in inspect_findings.cpp (Findings), inspect_manifest_fields.cpp (parseUntrustedJson) and
// inspect_layout.cpp (the rest, with inspect_manifest_figures.cpp for the frame and statistics blocks).
#pragma once

#include "common/file_hasher.hpp"
#include "printer_profiles/bitmap.hpp"
#include "printer_profiles/profile.hpp"

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

// Located findings: "JOB: ENTRY: message" or "JOB: message", capped at kMaxDefects.
class Findings {
public:
  static constexpr std::size_t kMaxDefects = 60;
  explicit Findings(std::string job) : job_(std::move(job)) {}
  // `entry` is a name from the job or the profile; it is shown with printableName().
  void at(const std::string& entry, const std::string& message);
  void whole(const std::string& message);
  // A message that already names the job and entry (a JobReadError's).
  void located(const std::string& message);
  void merge(const Findings& other);
  // An empty list for the same job, to gather findings that may be summarized instead of merged.
  Findings sibling() const { return Findings(job_); }
  bool empty() const { return list_.empty() && dropped_ == 0; }
  std::vector<std::string> take();  // the findings, with a count of those left out

private:
  void push(std::string text);
  std::string job_;
  std::vector<std::string> list_;
  std::size_t dropped_ = 0;
};

// What `inspect` allows at most for jobs of a profile: the tray bounds image size and layer count.
struct ProfileLimits {
  int maxWidth = 0, maxHeight = 0, maxLayers = 0;
  std::size_t maxEntries = 0;          // files and folders of the largest job
  std::uint64_t maxManifestBytes = 0;  // of the largest job's manifest
  std::size_t maxManifestValues = 0;   // JSON values in it
};
ProfileLimits limitsOf(const Profile& profile);

// Parses untrusted JSON (common::parseJsonStrict): throws std::runtime_error (message safe to print)
// when it is not JSON, nests deeper than common::kMaxJsonDepth or repeats a key in an object, and
// UntrustedJsonTooLarge (one) when it holds more than maxValues values; refused before the excess is built.
struct UntrustedJsonTooLarge : std::runtime_error {
  using std::runtime_error::runtime_error;
};
nlohmann::json parseUntrustedJson(std::span<const std::uint8_t> text, std::size_t maxValues);

enum class EntryRole { Manifest, BuildFile, Preview, ContactSheet, Layer, Report };

struct ExpectedEntry {
  EntryRole role = EntryRole::Layer;
  std::uint64_t maxBytes = 0;  // the most bytes the entry can hold in a sound job
  int layer = -1, material = -1;
};

// A file's checksum as the manifest gives it: XXH3-128 (jobs written since 2026-12-02) or SHA-256
// (jobs written before, still read).
struct FileDigest {
  common::HashAlgorithm algorithm = common::HashAlgorithm::Xxh128;
  std::string hex;  // lowercase
};

struct ListedFile {
  std::uint64_t bytes = 0;
  FileDigest digest;
};

struct OrientationRecord {
  std::uint64_t voxels = 0;
  std::array<double, 3> minMm{}, maxMm{}, centroidMm{};
};

// frame.part_voxels (the part's voxel box, index space) and frame.part_size_mm, as the manifest says.
struct PartRecord {
  std::array<std::int64_t, 3> min{}, max{};
  std::optional<std::array<double, 3>> sizeMm;
};

// One material's row of the manifest's "statistics" block.
struct MaterialStatistics {
  std::string role;
  std::uint64_t voxels = 0;
  double volumeMl = 0.0, massG = 0.0;
};

struct StatisticsRecord {
  std::vector<std::optional<MaterialStatistics>> materials;  // per job material (nullopt: missing or malformed)
  std::optional<std::uint64_t> modelVoxels;
  std::optional<std::uint64_t> clampedVoxels;  // below the floor and above the ceiling, when recorded
};

struct JobLayout {
  ImageFormat imageFormat = ImageFormat::Bmp;
  SupportPolicy support = SupportPolicy::Printer;
  int width = 0, height = 0, layers = 0;
  bool rgba = false;  // GrabCAD Voxel Print: one 8-bit RGBA image per layer holds every material
  std::vector<const ProfileMaterial*> materials;  // with bitmap stacks, in the job's order (by role)
  int firstColumnI = 0, topRowJ = 0, firstLayerK = 0;
  std::array<double, 3> originMm{};
  std::map<std::string, ExpectedEntry> expected;  // every entry the job must hold, manifest.json included
  std::map<std::string, ListedFile> listed;       // the manifest's file table (well-formed rows only)
  std::vector<std::vector<std::optional<std::uint64_t>>> layerVoxels;  // [layer][material] as the manifest says
  std::vector<std::optional<OrientationRecord>> orientation;           // per material (model materials)
  std::optional<PartRecord> part;                                      // nullopt: missing or malformed
  std::optional<StatisticsRecord> statistics;                          // nullopt: missing or not an object
};

// Checks the manifest against `profile` (every mismatch becomes a finding at "manifest.json: PATH")
// and derives the layout; nullopt when the numbers the layout needs are missing or out of the profile's
// range. `summary` fields are filled as they pass their checks.
struct InspectSummary;
std::optional<JobLayout> readLayout(const nlohmann::json& manifest, const Profile& profile, Findings& findings,
                                    InspectSummary& summary);

// The most bytes a PNG of `rawBytes` filtered image bytes can take (stored deflate blocks, small chunks).
std::uint64_t pngMaxBytes(std::uint64_t rawBytes);

}  // namespace rodfab::printer_profiles
