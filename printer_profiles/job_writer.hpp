// The job emitter: turns the material grid, band by band of layers, into the printer's bitmap stacks,
// its build file, previews and a manifest, written atomically as a zip archive or a directory.
#pragma once

#include "printer_profiles/job_archive.hpp"
#include "printer_profiles/job_layout.hpp"
#include "printer_profiles/profile.hpp"

#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rodfab::printer_profiles {

struct CalibrationRecord {
  std::string file;    // the name of the calibration file the mapping came from (a name, not a path)
  std::string sha256;  // its checksum, so a job can be traced to the exact data
  std::string rigidMaterial, rubberyMaterial;  // the materials it was measured on ("" when it does not say)
  std::string warning;  // why it may not fit this profile's materials ("" when it does)
};

// Voxels whose requested modulus lay outside what the materials can make (counted by materials/).
struct ModulusClamping {
  double floorMpa = 0.0, ceilingMpa = 0.0;
  std::uint64_t belowFloor = 0, aboveCeiling = 0;
};

struct JobMetadata {
  std::string design;          // design file the job was made from ("" if none)
  std::string ditherer;        // e.g. "white", "error-diffusion": isDithererLabel (the writer refuses others)
  std::uint64_t seed = 0;
  std::optional<CalibrationRecord> calibration;
  std::optional<ModulusClamping> clamping;
  nlohmann::json extra = nlohmann::json::object();  // caller's own records (e.g. coupon labels)
};

// Whether `label` may name a job's ditherer (JobMetadata::ditherer): up to 64 of a-z, 0-9 and '-' (empty:
// not said). What the writer refuses and inspect reports. Thread-safe.
bool isDithererLabel(std::string_view label);

// The job's report (report.html, see slicer/job_report.hpp), made by the caller from the manifest as it
// will be written (without its "files" table) and the rendered previews (name in the job, PNG bytes).
// Called once by finalize(), before the manifest; the bytes returned are written as kReportName and
// listed in the manifest's file table (and under "report") like any other file. May throw: the job is
// then not written.
using JobReportHook =
    std::function<Bytes(const nlohmann::json& manifest, const std::vector<std::pair<std::string, Bytes>>& previews)>;

// JobOptions::verify decodes one layer in this many (layers 0, n, 2n, ... and the last).
inline constexpr int kVerifyDecodeEvery = 32;

struct JobOptions {
  std::filesystem::path output;                  // the job: "NAME.zip" or a directory
  ArchiveFormat archive = ArchiveFormat::Zip;
  std::optional<ImageFormat> imageFormat;        // default: the profile's
  std::optional<SupportPolicy> support;          // default: the profile's
  // Replace a rodfab job at `output` (see OutputOccupant: recognised by its manifest). Anything else
  // there (a user's file or folder, a link, a job with files added) is never replaced.
  bool force = false;
  int contactSheetLayers = 16;                   // layers shown in previews/contact-sheet.png
  // Zip jobs: bytes of layer images in their zip form kept in memory until the zip is built; the rest
  // go to a file in the staging folder. Memory against two copies through the page cache; the job's
  // bytes are the same either way.
  std::uint64_t zipFormsInMemory = std::uint64_t{256} << 20;
  // Re-open and inspect before the rename: the layout, manifest, build file and previews as `inspect`
  // does; one layer in kVerifyDecodeEvery (and the last) decoded and checked against the manifest; every other layer
  // image's bytes as the zip stores them against the XXH3-128 the writer took when it staged them, and
  // its zip directory record (method, size, CRC-32) (folder jobs: every image's XXH3-128).
  bool verify = true;
  // Asked whether to stop (throw to stop; e.g. on SIGINT) as finalize() begins, after the zip is built,
  // immediately before the job is renamed into place and immediately after. Thrown after the rename,
  // the rename is undone (the new job removed, a job it replaced put back) before the exception
  // leaves finalize(). Called on the thread that calls finalize().
  std::function<void()> checkInterrupt;
  JobReportHook report;                          // empty: the job has no report.html
};

struct JobSpec {
  Profile profile;
  openvdb::CoordBBox partBounds;   // index box of every model voxel (the whole part, all bands)
  openvdb::Vec3d originMm;         // design-space position of the centre of voxel (0, 0, 0)
  JobMetadata metadata;
  JobOptions options;
  // Required by SupportPolicy::Explicit: the column tops of the whole part (see ColumnTops).
  std::shared_ptr<const ColumnTops> supportTops;
};

// Layers [kBegin, kEnd) of the part. `material` holds every model voxel of those layers (active =
// deposit; true = the rigid material, false = the rubbery one) and nothing outside them; its transform
// must be the profile's voxel size placed at JobSpec::originMm (voxel::printerTransform builds it). `modulus`
// (optional, MPa) colours the modulus previews.
struct LayerBand {
  openvdb::BoolGrid::ConstPtr material;
  openvdb::FloatGrid::ConstPtr modulus;
  int kBegin = 0, kEnd = 0;
};

struct MaterialTotals {
  std::string name;
  MaterialRole role = MaterialRole::Rigid;
  std::uint64_t voxels = 0;
  double volumeMl = 0.0, massG = 0.0;
};

struct JobResult {
  std::filesystem::path path;
  std::uint64_t device = 0, inode = 0;    // of the job at `path` as committed (see withdrawJob)
  JobGeometry geometry;
  std::vector<MaterialTotals> materials;  // in profile order
  std::size_t files = 0;                  // including the manifest
  std::uintmax_t bytes = 0;               // of the job on disk
};

// The absolute path a job with these options will have. Throws std::runtime_error naming it when its
// folder does not exist, when something is there that is not a rodfab job (saying what it is), or a
// rodfab job without options.force; std::invalid_argument for an empty path. The writer checks this
// again when it starts and when it commits; commands call it early to refuse before any work. First
// it cleans the folder of dead writers' staging (removeDeadStaging), putting back a job one of them had
// moved aside to replace it, so the output is examined as the commit will find it.
std::filesystem::path checkJobOutput(const JobOptions& options);

// Bytes a job's previews hold at the most while it is written (views and contact tiles), for a job
// of `geometry` (as planJob gives it) with `contactSheetLayers` (JobOptions; below 1 counts as 1): for
// memory estimates made before a job starts. Allocates at most one int per contact-sheet layer and reads
// only its arguments: safe to call from any number of threads at once. Throws std::invalid_argument when the
// geometry has no pixels or no layers (width, height or layers below 1), and std::bad_alloc when not
// even the few bytes it needs can be had.
std::uint64_t previewMemoryBytes(const JobGeometry& geometry, const Profile& profile, int contactSheetLayers);

// Writes one job. Usage: construct, addBand() for consecutive bands covering every layer of the
// part in increasing k, finalize(). addBand encodes the band (bitmaps, PNG/BMP, checksums, previews,
// compression) on TBB workers of the caller's task arena and returns when it is staged; a caller
// overlaps the next band's making with it on other threads (slicer's job pipeline does). One call at
// a time. The bytes written depend on the grids alone, not on the thread count or the band sizes.
// Until finalize() commits the job, everything lives in one hidden staging folder beside the target,
// ".NAME.rodfab-partial-PID-N", holding a lock file the writer keeps flock'ed while it lives; the
// destructor removes the folder on every path (errors, exceptions, interrupts). A killed process
// leaves only such a folder, which `inspect` refuses and which any later writer in the same output
// folder removes, whatever its target, once its lock is free. A job replaced under `force` is
// exchanged with the new one in one rename (renameat2 RENAME_EXCHANGE where the file system has it),
// so the target always holds one of the two. While a common::CommandOutputs owns the command's
// outputs (rodfab's main does), the replaced job is then moved beside the target as
// `.NAME.rodfab-old-PID-N` and kept until the command ends: removed when it succeeds, put back in
// place of the new job when it fails or is interrupted (common/interrupt.hpp). Without an owner it is
// removed with the staging folder when finalize() returns.
class JobWriter {
public:
  // Checks the profile and part against the tray (TrayFitError), and the target: free, or a rodfab
  // job with options.force (std::runtime_error naming the target and saying what is there
  // otherwise). Removes dead writers' staging folders in the output folder.
  explicit JobWriter(JobSpec spec);
  ~JobWriter();
  JobWriter(const JobWriter&) = delete;
  JobWriter& operator=(const JobWriter&) = delete;

  const JobGeometry& geometry() const;
  // What the manifest will record; figures known only after the last band (clamp counts) may be
  // filled in here before finalize().
  JobMetadata& metadata();
  ImageFormat imageFormat() const;
  SupportPolicy supportPolicy() const;

  // std::invalid_argument for a band out of order, a grid with the wrong voxel size or origin (a
  // 600/300 dpi swap is named as such), or voxels outside the band or the part bounds.
  void addBand(LayerBand band);
  // Writes the build file, previews and manifest, builds the zip, re-opens and inspects the job,
  // then renames it into place. std::runtime_error if a layer is missing, verification fails or the
  // target was taken meanwhile; whatever options.checkInterrupt throws passes through.
  JobResult finalize();

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Removes a job finalize() committed, when the caller must take it back (a signal that arrived after
// finalize returned): renamed aside to a staging name first, so a crash meanwhile never leaves half a
// job. Does nothing and returns false when `result.path` no longer holds that job (device and inode
// differ): only our own job is removed.
bool withdrawJob(const JobResult& result);

}  // namespace rodfab::printer_profiles
