// The job report: report.html inside every job `rodfab slice` writes, what a technician reads before a
// ten-hour print. One self-contained file (pictures embedded as data: URIs, no script, no fetch from
// the network), deterministic (the same job gives the same bytes: no date, no path of this machine).
//
// It shows: the checksums' verdict, warnings, print height and layer count, per-material voxels,
// volume and mass, the previews, the clamped moduli (counts, and a picture of where they are), the
// calibration used (file name, SHA-256, its fit plot) and the dithering. Every figure is taken from
// the manifest the writer passes (JobReportHook, printer_profiles/job_writer.hpp), so report and
// manifest cannot disagree; figures carry ids (e.g. id="layer-count", data-material rows) for tools.
#pragma once

#include "calibration/model.hpp"
#include "printer_profiles/bitmap.hpp"

#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::slicer {

// Where the voxels with a clamped modulus are: the part's voxels and the clamped ones projected on the
// top (x-y) and front (x-z) planes, in square bins of `binVoxels()` voxels a side (at most kMaxBins
// bins along any side). A voxel is below the floor when !(E >= floorMpa) (NaN too) and above the
// maximum when E > maxMpa: the classification of materials::FractionMap, so the totals equal the
// mapping's clamp counts.
class ClampMap {
public:
  static constexpr int kMaxBins = 320;

  // `part`: the part's voxel index box (not empty); `voxelSizeMm`: the printer's voxel (x, y, z) in mm.
  ClampMap(const openvdb::CoordBBox& part, const std::array<double, 3>& voxelSizeMm, double floorMpa, double maxMpa);

  // Counts the clamped active voxels and tiles of layers [k0, k1) of `modulus` (the rasterizer's
  // "modulus_mpa" grid of a band; values outside the part box are ignored) and draws the part as
  // addOutline does. Call once per band; not thread-safe.
  void add(const openvdb::FloatGrid& modulus, int k0, int k1);
  // Only the part: every leaf's whole 8-voxel cube (the rasterizer's leaves all hold active voxels) and
  // every active tile, within the part box; for bands without clamped voxels, at a five-hundredth of
  // add()'s cost. Counts nothing. Whole cubes, not clipped to the band's layers: a leaf that two bands
  // share is drawn alike from either, so the picture is the same whatever the bands (and threads) were.
  void addOutline(const openvdb::FloatGrid& modulus);

  std::uint64_t belowFloor() const { return below_; }
  std::uint64_t aboveMax() const { return above_; }
  int binVoxels() const { return bin_; }

  // The picture: the two views side by side to scale in mm, the part light grey, bins holding voxels
  // below the floor blue, above the maximum red (both: purple). Throws std::runtime_error when cairo fails.
  printer_profiles::Bytes renderPng() const;

private:
  struct View {
    int width = 0, height = 0;          // bins: (x, y) top, (x, z) front
    std::vector<std::uint8_t> model;    // 1 where the part has a voxel
    std::vector<std::uint64_t> below, above;
    void resize(int w, int h);
    void count(int u, int v, std::uint64_t n, int clamp);  // clamp: 0 none, 1 below, 2 above
  };
  void addBox(const openvdb::CoordBBox& box, float value);
  bool clip(openvdb::CoordBBox& box) const;  // to the part, relative to its corner; false when empty
  void outline(const openvdb::CoordBBox& box);  // marks the bins of a clipped box, counting nothing

  openvdb::CoordBBox part_;
  std::array<double, 3> voxelMm_;
  double floor_, max_;
  int bin_ = 1;
  View top_, front_;
  std::uint64_t below_ = 0, above_ = 0;
};

// What the report needs besides the manifest and the previews.
struct ReportInputs {
  const calibration::Calibration* calibration = nullptr;  // its fit plot is drawn; null: none recorded
  const ClampMap* clamps = nullptr;                       // null: no picture of the clamped voxels
  std::vector<std::string> warnings;                      // for the technician, shown at the top
  bool verified = true;  // the writer verifies the job before renaming it into place (JobOptions::verify)
};

// report.html for the job described by `manifest` (the writer's, without its "files" table) and its
// rendered `previews` (name in the job, PNG bytes). Throws std::runtime_error when the manifest lacks
// a figure the writer always records, or cairo fails to draw a picture.
std::string renderJobReport(const nlohmann::json& manifest, const std::vector<std::pair<std::string, printer_profiles::Bytes>>& previews,
                            const ReportInputs& inputs);

}  // namespace rodfab::slicer
