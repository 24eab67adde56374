#include "printer_profiles/job_manifest.hpp"

namespace rodfab::printer_profiles {

using nlohmann::json;

namespace {

json profileBlock(const Profile& p) {
  json j = {{"name", p.name},
            {"printer", p.printer},
            {"x_dpi", p.xDpi},
            {"y_dpi", p.yDpi},
            {"voxel_size_mm", p.voxelSizeMm},
            {"layer_thickness_mm", p.layerThicknessMm()},
            {"tray_mm", p.trayMm},
            {"column_alignment", p.columnAlignment}};
  if (!p.printMode.empty()) j["print_mode"] = p.printMode;
  return j;
}

json imageBlock(const ManifestInputs& in) {
  const Profile& p = in.spec.profile;
  return {{"format", toString(in.form.imageFormat)},
          {"bit_depth", p.imageBitDepth()},
          {"width", in.form.geometry.width},
          {"height", in.form.geometry.height},
          {"x_pixels_per_metre", pixelsPerMetre(p.xDpi)},
          {"y_pixels_per_metre", pixelsPerMetre(p.yDpi)},
          {"origin", "top-left"},
          {"row_order", p.rowOrder}};
}

json frameBlock(const ManifestInputs& in) {
  const auto& v = in.spec.profile.voxelSizeMm;
  const openvdb::Vec3d& o = in.spec.originMm;
  const openvdb::CoordBBox& part = in.form.geometry.partBounds;
  return {{"origin_mm", {o.x(), o.y(), o.z()}},
          {"origin_note", "design position of the centre of voxel (0, 0, 0)"},
          {"first_column_i", in.form.geometry.firstColumnI},
          {"top_row_j", in.form.geometry.topRowJ},
          {"first_layer_k", in.form.geometry.firstLayerK},
          {"pixel_to_design_mm",
           "x = origin_x + (first_column_i + column) * voxel_x; y = origin_y + (top_row_j - row) * voxel_y; "
           "z = origin_z + (first_layer_k + layer) * voxel_z"},
          {"part_voxels", {{"min", {part.min().x(), part.min().y(), part.min().z()}}, {"max", {part.max().x(), part.max().y(), part.max().z()}}}},
          {"part_size_mm", {part.dim().x() * v[0], part.dim().y() * v[1], part.dim().z() * v[2]}}};
}

json materialsBlock(const ManifestInputs& in) {
  json materials = json::array();
  for (const ProfileMaterial* m : in.form.emitted)
    materials.push_back({{"name", m->name},
                         {"role", toString(m->role)},
                         {"density_g_per_ml", m->densityGPerMl},
                         {"file_pattern", in.spec.profile.layerFilePattern(*m, in.form.imageFormat)}});
  return materials;
}

json supportBlock(const ManifestInputs& in) {
  return {{"policy", toString(in.form.support)},
          {"material", in.spec.profile.material(MaterialRole::Support).name},
          {"note", in.form.support == SupportPolicy::Printer ? "no support bitmaps: the printer software adds support"
                                                        : "support bitmaps fill every column from the tray up to its "
                                                          "highest model voxel, never overlapping the model"}};
}

// The per-layer table; adds every layer's voxels to `totals` (by role) and moments to `moments`.
json layersBlock(const ManifestInputs& in, std::array<std::uint64_t, 3>& totals, std::array<Moments, 2>& moments) {
  json layerFiles = json::array();
  for (int l = 0; l < in.form.geometry.layers; ++l) {
    const LayerRecord& r = in.layers[static_cast<std::size_t>(l)];
    json filesOf = json::object(), voxelsOf = json::object();
    for (const ProfileMaterial* m : in.form.emitted) {
      filesOf[m->name] = in.spec.profile.layerFileName(*m, l, in.form.imageFormat);  // gcvf: one file for all
      voxelsOf[m->name] = r.voxels[static_cast<std::size_t>(m->role)];
    }
    layerFiles.push_back({{"layer", l}, {"files", filesOf}, {"voxels", voxelsOf}});
    for (int role = 0; role < 3; ++role) totals[role] += r.voxels[role];
    moments[0].merge(r.moments[0]);
    moments[1].merge(r.moments[1]);
  }
  return layerFiles;
}

json calibrationBlock(const std::optional<CalibrationRecord>& c) {
  if (!c) return nullptr;
  return {{"file", c->file},
          {"sha256", c->sha256},
          {"materials", c->rigidMaterial.empty() ? json(nullptr) : json{{"rigid", c->rigidMaterial}, {"rubbery", c->rubberyMaterial}}},
          {"warning", c->warning.empty() ? json(nullptr) : json(c->warning)}};
}

json statisticsBlock(const ManifestInputs& in, const std::array<std::uint64_t, 3>& totals) {
  const Profile& p = in.spec.profile;
  json stats = json::object();
  std::uint64_t model = 0;
  for (const ProfileMaterial* m : in.form.emitted) {
    const std::uint64_t n = totals[static_cast<std::size_t>(m->role)];
    const double ml = static_cast<double>(n) * p.voxelVolumeMm3() / 1000.0;
    stats[m->name] = {{"role", toString(m->role)}, {"voxels", n}, {"volume_ml", ml}, {"mass_g", ml * m->densityGPerMl}};
    if (m->role != MaterialRole::Support) model += n;
  }
  json j = {{"materials", stats}, {"model_voxels", model}};
  if (in.spec.metadata.clamping) {
    const ModulusClamping& c = *in.spec.metadata.clamping;
    j["clamped_modulus"] = {{"floor_mpa", c.floorMpa},
                            {"ceiling_mpa", c.ceilingMpa},
                            {"below_floor_voxels", c.belowFloor},
                            {"above_ceiling_voxels", c.aboveCeiling}};
  } else {
    j["clamped_modulus"] = nullptr;
  }
  return j;
}

// Computed from the grid, not the images: `inspect` decodes the images, maps pixels back with the
// frame and must land on the same boxes and centroids, or the images are mirrored or rotated.
json orientationBlock(const ManifestInputs& in, const std::array<Moments, 2>& moments) {
  const auto& v = in.spec.profile.voxelSizeMm;
  const openvdb::Vec3d& o = in.spec.originMm;
  const auto toMm = [&](const openvdb::Vec3d& ijk) {
    return json::array({o.x() + ijk.x() * v[0], o.y() + ijk.y() * v[1], o.z() + ijk.z() * v[2]});
  };
  json orientation = json::object();
  for (int m = 0; m < 2; ++m) {
    const Moments& mo = moments[static_cast<std::size_t>(m)];
    const std::string& name = in.spec.profile.material(m == 0 ? MaterialRole::Rigid : MaterialRole::Rubbery).name;
    if (!mo.count) {
      orientation[name] = {{"voxels", 0}};
      continue;
    }
    const double n = static_cast<double>(mo.count);
    orientation[name] = {{"voxels", mo.count},
                         {"min_mm", toMm(mo.min.asVec3d())},
                         {"max_mm", toMm(mo.max.asVec3d())},
                         {"centroid_mm", toMm(openvdb::Vec3d(mo.sum[0] / n, mo.sum[1] / n, mo.sum[2] / n))}};
  }
  return orientation;
}

}  // namespace

json jobManifest(const ManifestInputs& in, const std::vector<FileRecord>& files, const std::vector<std::string>& previewNames) {
  const JobSpec& spec = in.spec;
  json j;
  j["format"] = kJobFormat;
  j["profile"] = profileBlock(spec.profile);
  j["image"] = imageBlock(in);
  j["layer_count"] = in.form.geometry.layers;
  j["frame"] = frameBlock(in);
  j["materials"] = materialsBlock(in);
  j["support"] = supportBlock(in);
  j["build_file"] = spec.profile.buildFileName;
  std::array<std::uint64_t, 3> totals{};
  std::array<Moments, 2> moments;
  j["layers"] = layersBlock(in, totals, moments);
  j["dithering"] = {{"ditherer", spec.metadata.ditherer}, {"seed", spec.metadata.seed}};
  j["calibration"] = calibrationBlock(spec.metadata.calibration);
  j["statistics"] = statisticsBlock(in, totals);
  j["orientation_check"] = orientationBlock(in, moments);
  j["previews"] = previewNames;
  if (spec.options.report) j["report"] = kReportName;
  j["contact_sheet_layers"] = in.contactLayers;
  json meta = spec.metadata.extra.is_object() ? spec.metadata.extra : json::object();
  meta["design"] = spec.metadata.design;
  j["metadata"] = meta;
  json fileTable = json::object();
  for (const FileRecord& f : files) fileTable[f.name] = {{"bytes", f.bytes}, {"xxh128", f.xxh128}};
  j["files"] = fileTable;
  return j;
}

}  // namespace rodfab::printer_profiles
