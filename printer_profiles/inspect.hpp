// Re-reading a job, which may be damaged or hostile: the job's complete layout against its printer
// profile (every expected file present with a size its images can have, nothing else, names safe on
// every platform), every checksum, image size, bit depth, DPI and axis orientation, model materials never
// overlapping, support never overlapping the model, the build file against the profile and manifest.
//
// Nothing in the job is trusted. The profile is chosen by the caller or, by name only, among the bundled
// profiles (a manifest never names a file to read); every entry is streamed with a cap on its bytes
// derived from the profile's tray and the job's image size; folder jobs are walked without following
// links and only regular files are opened; the manifest is refused when larger, more deeply nested
// (64 levels) or holding more values than a job for that profile can need. Memory stays bounded: at most
// a few layers' images (each capped) are held at once.
#pragma once

#include "printer_profiles/job_archive.hpp"
#include "printer_profiles/job_writer.hpp"
#include "printer_profiles/profile.hpp"

#include <nlohmann/json.hpp>

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

// A zip entry as its writer staged it: what the writer's verification compares the archive with.
struct StoredForm {
  std::string xxh128;            // of the entry's bytes as stored (deflated, or the file itself)
  std::uint64_t storedBytes = 0; // their length
  std::uint32_t crc32 = 0;       // of the contents, for the zip's directory
  bool deflated = true;          // how the zip's directory must say it is stored: deflated, or as it is
};

struct InspectOptions {
  // The profile the job must match. Default: the bundled profile whose name the manifest gives (a
  // portable name that is not bundled leaves the job not checked, InspectReport::notChecked: pass the
  // profile file's contents here instead; a name no profile can have is a defect. So does a manifest
  // larger than any bundled profile's job can have, which is a defect when the profile is given).
  std::optional<Profile> profile;
  // For the writer's check of its own job (JobOptions::verify); `inspect` keeps the defaults, which
  // check everything. Layer images are decoded and checked (size, resolution, counts against the
  // manifest, no voxel of two materials) in layers 0, n, 2n, ... and the last one, n = decodeEvery
  // (values below 1 count as 1). Every other layer image is still read through, its size checked
  // against the manifest. When not every layer is decoded, InspectReport::materials counts the
  // decoded layers only and the orientation check (which needs every voxel) is not made.
  int decodeEvery = 1;
  // In a zip job, a layer image that is not decoded and is named here is checked by its stored form
  // instead of being inflated and hashed: its bytes as the archive holds them must have this length
  // and XXH3-128, and the zip's directory must record this method and CRC-32 and the manifest's size.
  // Enough for the writer, which recorded these as it staged the bytes it had hashed for the manifest
  // (printer_profiles/README.md, "What the writer's own verification checks"); never for a job from
  // elsewhere. Images not named here are checked as usual.
  std::map<std::string, StoredForm> storedForms{};
};

// What the job says about itself, filled only from values that passed their checks.
struct InspectSummary {
  std::string profile, printer;   // of the profile the job was checked against
  int xDpi = 0, yDpi = 0;
  double layerThicknessMm = 0.0;
  std::string imageFormat;        // "bmp" | "png"
  int bitDepth = 0;               // bits per pixel of the layer images (1, or 32 for RGBA)
  std::string supportPolicy;      // "printer" | "explicit"
  std::optional<std::array<double, 3>> partSizeMm;
  std::string ditherer;
  std::optional<std::uint64_t> seed;
};

struct InspectReport {
  std::filesystem::path job;
  // Empty: the job is sound. Each defect is located: "JOB: ENTRY: what was expected" for one entry (for
  // the manifest, the JSON path follows the entry), "JOB: what was expected" for the whole job. Names
  // from the job are shown with non-printable bytes as \xNN. At most 60, then a count of the rest.
  std::vector<std::string> defects;
  nlohmann::json manifest;  // null when it could not be read
  InspectSummary summary;
  std::size_t filesChecked = 0;
  // Of those, copies of a layer image already checked and decoded blank, compared byte for byte as the
  // zip stores them (and by their directory record) instead of inflated and decoded again.
  std::size_t blankCopiesComparedStored = 0;
  int width = 0, height = 0, layers = 0;
  std::vector<MaterialTotals> materials;  // counted from the decoded images, in the job's material order
  // Why the job could not be checked, empty when it was: the manifest names a printer profile that is
  // not bundled and none was given (InspectOptions::profile), so its layout is unknown. Such a job is
  // not sound as far as anyone can tell, nor found defective; `defects` still lists what no job of any
  // profile may hold (unsafe names, duplicate entries, links).
  std::string notChecked;

  bool checked() const { return notChecked.empty(); }
  bool ok() const { return defects.empty() && checked(); }
};

// Never throws for a damaged or hostile job: every problem becomes a defect. A path with the emitter's
// temporary name is refused as unfinished. `job` itself may be a symbolic link; a path that is neither a
// folder nor a regular file (FIFO, device) is refused without reading it. Thread-safe for distinct calls;
// uses TBB workers internally.
InspectReport inspectJob(const std::filesystem::path& job, const InspectOptions& options = {});

}  // namespace rodfab::printer_profiles
