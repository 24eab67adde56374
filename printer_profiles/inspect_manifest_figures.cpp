// Reading the manifest's figures about the part: the "frame" block (where the images stand in the
// profile's voxel index space, the part's box and size) and the "statistics" block (per material voxels,
// volume and mass; the model's voxels; the clamped moduli). Only their form is checked here; their
// agreement with the images, the layers and the profile is Inspector's (inspect_statistics.cpp).
#include "printer_profiles/inspect_manifest_fields.hpp"

#include "printer_profiles/inspect.hpp"

#include "common/json_input.hpp"

#include <algorithm>
#include <cstdint>

namespace rodfab::printer_profiles::manifest_input {

using common::indexPath;
using common::memberPath;

namespace {

// frame.part_voxels: {"min": [i, j, k], "max": [i, j, k]}, min <= max (checked against the rest of the
// frame and the images by Inspector::checkPart).
void readPartVoxels(const json& frame, JobLayout& out, Fields& f) {
  constexpr std::int64_t kIndexRange = 1 << 28;
  const json* box = f.object(frame, "frame", "part_voxels");
  if (!box) return;
  PartRecord part;
  for (const char* corner : {"min", "max"}) {
    const std::string path = memberPath("frame.part_voxels", corner);
    const json* v = f.array(*box, "frame.part_voxels", corner);
    if (!v || v->size() != 3) {
      if (v) f.fail(path, "expected three voxel indices, got " + std::to_string(v->size()) + " values");
      return;
    }
    for (std::size_t a = 0; a < 3; ++a) {
      const auto index = f.integer((*v)[a], indexPath(path, a), -kIndexRange, kIndexRange);
      if (!index) return;
      (corner == std::string("min") ? part.min : part.max)[a] = *index;
    }
  }
  for (std::size_t a = 0; a < 3; ++a)
    if (part.min[a] > part.max[a]) {
      f.fail("frame.part_voxels", "min is above max along " + std::string(1, "xyz"[a]) + "; expected a box of voxels");
      return;
    }
  out.part = part;
}

std::optional<MaterialStatistics> readMaterialStatistics(const json& list, const std::string& name, Fields& f) {
  const json* row = f.object(list, "statistics.materials", name);
  if (!row) return std::nullopt;
  const std::string path = memberPath("statistics.materials", name);
  const auto role = f.string(*row, path, "role");
  const json* voxels = f.get(*row, path, "voxels", "a voxel count");
  const auto count = voxels ? f.count(*voxels, memberPath(path, "voxels")) : std::nullopt;
  const auto volume = f.number(*row, path, "volume_ml");
  const auto mass = f.number(*row, path, "mass_g");
  if (!role || !count || !volume || !mass) return std::nullopt;
  return MaterialStatistics{*role, *count, *volume, *mass};
}

// statistics.clamped_modulus: null, or the floor and ceiling (MPa) and the voxels clamped to each.
std::optional<std::uint64_t> readClamped(const json& block, Fields& f) {
  const json* clamped = f.get(block, "statistics", "clamped_modulus", "null or an object");
  if (!clamped || clamped->is_null()) return std::nullopt;
  clamped = f.object(block, "statistics", "clamped_modulus");
  if (!clamped) return std::nullopt;
  const std::string path = "statistics.clamped_modulus";
  const auto floor = f.number(*clamped, path, "floor_mpa"), ceiling = f.number(*clamped, path, "ceiling_mpa");
  if (floor && ceiling && !(*floor > 0 && *floor <= *ceiling))
    f.fail(path, "expected 0 < floor_mpa <= ceiling_mpa, got " + describe(json(*floor)) + " and " + describe(json(*ceiling)));
  std::uint64_t total = 0;
  bool counted = true;
  for (const char* key : {"below_floor_voxels", "above_ceiling_voxels"}) {
    const json* v = f.get(*clamped, path, key, "a voxel count");
    const std::uint64_t n = v ? f.count(*v, path + "." + key).value_or(UINT64_MAX) : UINT64_MAX;  // UINT64_MAX: not a count
    counted = counted && n != UINT64_MAX && n <= UINT64_MAX - total;
    if (counted) total += n;
  }
  if (!counted) return std::nullopt;
  return total;
}

}  // namespace

void readFrame(const json& m, JobLayout& out, Fields& f, InspectSummary& s) {
  const json* frame = f.object(m, "", "frame");
  if (!frame) return;
  constexpr std::int64_t kIndexRange = 1 << 28;  // far beyond any tray; keeps pixel arithmetic in int
  if (const auto o = f.vec3(*frame, "frame", "origin_mm")) out.originMm = *o;
  out.firstColumnI = static_cast<int>(f.integer(*frame, "frame", "first_column_i", -kIndexRange, kIndexRange).value_or(0));
  out.topRowJ = static_cast<int>(f.integer(*frame, "frame", "top_row_j", -kIndexRange, kIndexRange).value_or(0));
  out.firstLayerK = static_cast<int>(f.integer(*frame, "frame", "first_layer_k", -kIndexRange, kIndexRange).value_or(0));
  s.partSizeMm = f.vec3(*frame, "frame", "part_size_mm");
  readPartVoxels(*frame, out, f);
  if (out.part) out.part->sizeMm = s.partSizeMm;
}

// The "statistics" block: per job material its role, voxels, volume and mass; the model's voxels; the
// clamped moduli (null when the job had none to clamp). Compared with the layers and images by
// Inspector::checkStatistics.
void readStatistics(const json& m, JobLayout& out, Fields& f) {
  const json* block = f.object(m, "", "statistics");
  if (!block) return;
  StatisticsRecord stats;
  stats.materials.resize(out.materials.size());
  if (const json* list = f.object(*block, "statistics", "materials")) {
    for (const auto& item : list->items()) {  // not a structured binding: clang 14 cannot capture one in the lambda
      const std::string& name = item.key();
      if (std::none_of(out.materials.begin(), out.materials.end(), [&](const ProfileMaterial* p) { return p->name == name; }))
        f.fail(memberPath("statistics.materials", name), "is not one of the job's materials");
    }
    for (std::size_t n = 0; n < out.materials.size(); ++n) stats.materials[n] = readMaterialStatistics(*list, out.materials[n]->name, f);
  }
  if (const json* model = f.get(*block, "statistics", "model_voxels", "a voxel count")) stats.modelVoxels = f.count(*model, "statistics.model_voxels");
  stats.clampedVoxels = readClamped(*block, f);
  out.statistics = stats;
}

}  // namespace rodfab::printer_profiles::manifest_input
