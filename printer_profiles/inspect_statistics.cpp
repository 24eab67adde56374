// The manifest's figures that the rest of the job determines: the "statistics" block against the
// layers' voxel counts (each checked against its images) and the profile, and the part's box
// (frame.part_voxels, frame.part_size_mm) against the frame planJob derives from it and the images.
// A figure that disagrees is a defect, as a layer count that disagrees with its image is: a summary,
// a report or a technician reads these figures, and nothing else vouches for them.
#include "printer_profiles/inspector.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rodfab::printer_profiles::detail {

namespace {

bool nearlyEqual(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max({1.0, std::abs(a), std::abs(b)}); }

std::string number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

// planJob's rounding (job_layout.cpp), restated: the inspector does not share the writer's code.
std::int64_t floorToMultiple(std::int64_t v, std::int64_t m) { return (v >= 0 ? v / m : -((-v + m - 1) / m)) * m; }
std::int64_t ceilToMultiple(std::int64_t v, std::int64_t m) { return (v + m - 1) / m * m; }

}  // namespace

// The sum of the manifest's per-layer counts of material `n`, when every layer lists one.
std::optional<std::uint64_t> Inspector::listedVoxels(std::size_t n) const {
  std::uint64_t sum = 0;
  for (const auto& layer : layout_.layerVoxels) {
    if (!layer[n]) return std::nullopt;
    sum += *layer[n];
  }
  return sum;
}

void Inspector::checkStatistics() {
  if (!layout_.statistics) return;
  const StatisticsRecord& stats = *layout_.statistics;
  const auto& v = profile_.voxelSizeMm;
  std::uint64_t model = 0;
  bool modelKnown = true;  // every model material's row read (a plain flag: GCC 12 warns falsely on an optional here)
  for (std::size_t n = 0; n < layout_.materials.size(); ++n) {
    const ProfileMaterial& m = *layout_.materials[n];
    const std::optional<MaterialStatistics>& row = stats.materials[n];
    if (!row) {
      if (m.role != MaterialRole::Support) modelKnown = false;
      continue;
    }
    const std::string path = "statistics.materials." + m.name + ".";
    const auto fail = [&](const std::string& message) { findings_.at(kManifestName, path + message); };
    if (row->role != toString(m.role))
      fail("role: expected \"" + std::string(toString(m.role)) + "\", got \"" + printableName(row->role) + "\"");
    if (const auto layers = listedVoxels(n); layers && *layers != row->voxels)
      fail("voxels: " + std::to_string(row->voxels) + ", but the layers' counts (layers[].voxels." + m.name + "), each checked against its image, add up to " +
           std::to_string(*layers));
    const double ml = static_cast<double>(row->voxels) * v[0] * v[1] * v[2] / 1000.0;
    if (!nearlyEqual(row->volumeMl, ml))
      fail("volume_ml: " + number(row->volumeMl) + ", but " + std::to_string(row->voxels) + " voxels of the profile's " + number(v[0]) + " x " +
           number(v[1]) + " x " + number(v[2]) + " mm are " + number(ml) + " mL");
    if (!nearlyEqual(row->massG, ml * m.densityGPerMl))
      fail("mass_g: " + number(row->massG) + ", but " + number(ml) + " mL at the profile's " + number(m.densityGPerMl) + " g/mL are " +
           number(ml * m.densityGPerMl) + " g");
    if (m.role != MaterialRole::Support) model += row->voxels;
  }
  if (stats.modelVoxels && modelKnown && *stats.modelVoxels != model)
    findings_.at(kManifestName, "statistics.model_voxels: " + std::to_string(*stats.modelVoxels) + ", but the model materials' voxels add up to " +
                                    std::to_string(model));
  // Clamped voxels are model voxels: against the materials' total, or model_voxels when a row is missing.
  const std::uint64_t modelTotal = modelKnown ? model : stats.modelVoxels.value_or(UINT64_MAX);
  if (stats.clampedVoxels && *stats.clampedVoxels > modelTotal)
    findings_.at(kManifestName, "statistics.clamped_modulus: " + std::to_string(*stats.clampedVoxels) + " voxels clamped, more than the " +
                                    std::to_string(modelTotal) + " of the model");
}

void Inspector::checkPart(const std::vector<DecodedMoments>& moments, bool everyLayerDecoded) {
  if (!layout_.part) return;
  const PartRecord& part = *layout_.part;
  const std::array<std::int64_t, 3> dim = {part.max[0] - part.min[0] + 1, part.max[1] - part.min[1] + 1, part.max[2] - part.min[2] + 1};
  checkFrameOfPart(part, dim);
  const auto& v = profile_.voxelSizeMm;
  if (part.sizeMm)
    for (int a = 0; a < 3; ++a)
      if (!nearlyEqual((*part.sizeMm)[a], static_cast<double>(dim[a]) * v[a])) {
        findings_.at(kManifestName, "frame.part_size_mm: " + number((*part.sizeMm)[a]) + " mm along " + "xyz"[a] + ", but frame.part_voxels spans " +
                                        std::to_string(dim[a]) + " voxels of " + number(v[a]) + " mm = " + number(static_cast<double>(dim[a]) * v[a]) + " mm");
        break;
      }
  if (!everyLayerDecoded) return;  // the images' extent needs every layer
  for (std::size_t n = 0; n < layout_.materials.size(); ++n) {
    const DecodedMoments& mo = moments[n];
    if (layout_.materials[n]->role == MaterialRole::Support || !mo.count) continue;
    bool inside = true;
    for (int a = 0; a < 3; ++a) inside = inside && mo.min[a] >= part.min[a] && mo.max[a] <= part.max[a];
    if (!inside)
      findings_.whole(layout_.materials[n]->name + ": the images hold voxels from (" + std::to_string(mo.min[0]) + ", " + std::to_string(mo.min[1]) +
                      ", " + std::to_string(mo.min[2]) + ") to (" + std::to_string(mo.max[0]) + ", " + std::to_string(mo.max[1]) + ", " +
                      std::to_string(mo.max[2]) + "), outside the part's box in manifest.json's frame.part_voxels");
  }
}

// The frame as planJob derives it from the part's box and the profile's padding and alignment.
void Inspector::checkFrameOfPart(const PartRecord& part, const std::array<std::int64_t, 3>& dim) {
  const auto& pad = profile_.paddingVoxels;
  const std::int64_t firstColumn = floorToMultiple(part.min[0] - pad[0], 8);
  const std::int64_t width = ceilToMultiple(part.max[0] + pad[0] - firstColumn + 1, std::max(1, profile_.columnAlignment));
  const struct {
    const char* field;
    std::int64_t got, want;
  } derived[] = {{"frame.first_column_i", layout_.firstColumnI, firstColumn},
                 {"image.width", layout_.width, width},
                 {"frame.top_row_j", layout_.topRowJ, part.max[1] + pad[1]},
                 {"image.height", layout_.height, dim[1] + 2 * pad[1]},
                 {"frame.first_layer_k", layout_.firstLayerK, part.min[2]},
                 {"layer_count", layout_.layers, dim[2]}};
  for (const auto& d : derived)
    if (d.got != d.want)
      findings_.at(kManifestName, std::string(d.field) + ": " + std::to_string(d.got) + ", but a part of frame.part_voxels from (" +
                                      std::to_string(part.min[0]) + ", " + std::to_string(part.min[1]) + ", " + std::to_string(part.min[2]) + ") to (" +
                                      std::to_string(part.max[0]) + ", " + std::to_string(part.max[1]) + ", " + std::to_string(part.max[2]) + ") with " +
                                      profile_.name + "'s padding and alignment gives " + std::to_string(d.want));
}

}  // namespace rodfab::printer_profiles::detail
