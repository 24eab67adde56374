// Reading the sections of a printer profile and the checks across them (profile_validator.hpp); the
// document itself is read in profile_reader.cpp.
#include "printer_profiles/profile_validator.hpp"

#include "printer_profiles/job_archive.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>

namespace rodfab::printer_profiles::detail {

void readResolution(Validator& v, const json& doc, Profile& p) {
  const json* res = v.object(doc, "", "resolution");
  if (!res) return;
  p.xDpi = v.require(*res, "resolution", "x_dpi", "dots per inch along x (image columns)")
               ? v.integer((*res)["x_dpi"], "resolution.x_dpi", "dots per inch along x", 1, 100000).value_or(0)
               : 0;
  p.yDpi = v.require(*res, "resolution", "y_dpi", "dots per inch along y (image rows)")
               ? v.integer((*res)["y_dpi"], "resolution.y_dpi", "dots per inch along y", 1, 100000).value_or(0)
               : 0;
  std::optional<double> layer;
  if (const json* t = v.require(*res, "resolution", "layer_thickness_mm", "the layer thickness in mm"))
    layer = v.real(*t, "resolution.layer_thickness_mm", "a layer thickness in mm", kMinVoxelMm, kMaxVoxelMm, true);
  const bool sizesOk = v.array<3>(*res, "resolution", "voxel_size_mm", "voxel sizes in mm (x, y, z)",
                                  [&](const json& j, const std::string& path, std::size_t i) {
                                    auto s = v.real(j, path, "a voxel size in mm", kMinVoxelMm, kMaxVoxelMm, true);
                                    if (s) p.voxelSizeMm[i] = *s;
                                    return s.has_value();
                                  });
  // The dpi and the voxel size must tell the same story, so a 600/300 swap in either one is caught here.
  const int dpi[2] = {p.xDpi, p.yDpi};
  const char* axis[2] = {"x", "y"};
  for (int a = 0; a < 2 && sizesOk; ++a) {
    if (dpi[a] <= 0) continue;
    const double fromDpi = 25.4 / dpi[a];
    if (std::abs(p.voxelSizeMm[a] - fromDpi) > 0.005 * fromDpi) {
      std::ostringstream msg;
      msg << "voxel size along " << axis[a] << " is " << p.voxelSizeMm[a] << " mm but " << axis[a] << "_dpi = " << dpi[a]
          << " means " << fromDpi << " mm";
      if (std::abs(p.voxelSizeMm[a] - 25.4 / dpi[1 - a]) < 0.005 * p.voxelSizeMm[a])
        msg << " (x and y look swapped: x is the image columns, y the image rows)";
      v.fail(indexPath("resolution.voxel_size_mm", a), msg.str());
    }
  }
  if (sizesOk && layer && std::abs(*layer - p.voxelSizeMm[2]) > 1e-9)
    v.fail("resolution.voxel_size_mm[2]", "expected the layer thickness " + std::to_string(*layer) + " mm");
}

namespace {

// An RGBA colour: four components 0..255.
void readRgba(Validator& v, const json& parent, const std::string& path, const std::string& key, std::array<unsigned char, 4>& out) {
  v.array<4>(parent, path, key, "colour components 0..255 (red, green, blue, alpha)", [&](const json& j, const std::string& cp, std::size_t c) {
    auto value = v.integer(j, cp, "a colour component", 0, 255);
    if (value) out[c] = static_cast<unsigned char>(*value);
    return value.has_value();
  });
}

}  // namespace

// "output": {"format": "bitmap-stacks" | "gcvf"}, optional (bitmap stacks); "gcvf" needs the "gcvf" block.
void readOutput(Validator& v, const json& doc, Profile& p) {
  if (!doc.contains("output")) return;
  const json* out = v.object(doc, "", "output");
  if (!out) return;
  const std::optional<std::string> format = v.string(*out, "output", "format");
  if (format == "gcvf") p.jobFormat = JobFormat::Gcvf;
  else if (format && *format != "bitmap-stacks") v.fail("output.format", "expected \"bitmap-stacks\" or \"gcvf\", got \"" + *format + "\"");
  if (p.jobFormat != JobFormat::Gcvf) return;
  const json* g = v.object(doc, "", "gcvf");
  if (!g) return;
  if (const json* n = v.require(*g, "gcvf", "version", "the ConfigFile.xml version"))
    p.gcvf.version = v.integer(*n, "gcvf.version", "a version", 1, 1000).value_or(2);
  if (const json* n = v.require(*g, "gcvf", "bit_depth", "the ConfigFile.xml BitDepth"))
    p.gcvf.bitDepth = v.integer(*n, "gcvf.bit_depth", "a bit depth", 1, 64).value_or(4);
  if (const json* n = v.require(*g, "gcvf", "max_number_of_colors", "how many colours the printer takes"))
    p.gcvf.maxNumberOfColors = v.integer(*n, "gcvf.max_number_of_colors", "a colour count", 2, 64).value_or(6);
  p.gcvf.creationMode = v.string(*g, "gcvf", "creation_mode", 64).value_or("");
  if (auto prefix = v.fileName(*g, "gcvf", "image_file_prefix")) p.gcvf.imageFilePrefix = *prefix;
  readRgba(v, *g, "gcvf", "background_rgba", p.gcvf.backgroundRgba);
}

// "resolution.print_modes": [{"name", "layer_thickness_mm"}, ...], optional; the first is the default and
// must be the profile's layer thickness.
void readPrintModes(Validator& v, const json& doc, Profile& p) {
  const json* res = doc.contains("resolution") && doc["resolution"].is_object() ? &doc["resolution"] : nullptr;
  if (!res || !res->contains("print_modes")) return;
  const json& modes = (*res)["print_modes"];
  if (!modes.is_array() || modes.empty() || modes.size() > 16) {
    v.fail("resolution.print_modes", "expected an array of 1 to 16 print modes, got " + describeJson(modes));
    return;
  }
  std::set<std::string> names;
  for (std::size_t i = 0; i < modes.size(); ++i) {
    const std::string path = indexPath("resolution.print_modes", i);
    if (!modes[i].is_object()) {
      v.fail(path, "expected an object, got " + describeJson(modes[i]));
      continue;
    }
    PrintMode mode;
    mode.name = v.fileName(modes[i], path, "name").value_or("");
    if (!mode.name.empty() && !names.insert(mode.name).second) v.fail(memberPath(path, "name"), "\"" + mode.name + "\" is named twice");
    if (const json* t = v.require(modes[i], path, "layer_thickness_mm", "the layer thickness in mm"))
      mode.layerThicknessMm = v.real(*t, memberPath(path, "layer_thickness_mm"), "a layer thickness in mm", kMinVoxelMm, kMaxVoxelMm, true).value_or(0);
    p.printModes.push_back(mode);
  }
  if (!p.printModes.empty() && p.voxelSizeMm[2] > 0 && std::abs(p.printModes[0].layerThicknessMm - p.voxelSizeMm[2]) > 1e-9)
    v.fail("resolution.print_modes[0].layer_thickness_mm", "expected the profile's layer thickness " + number(p.voxelSizeMm[2]) +
                                                                " mm: the first mode is the default");
  p.printMode = p.printModes.empty() ? "" : p.printModes[0].name;
}

// A gcvf profile: the format's fixed names, RGBA images, colours that tell the materials apart.
void checkGcvf(Validator& v, const Profile& p) {
  if (p.imageFormat != ImageFormat::Png) v.fail("image.format", "expected \"png\": GrabCAD Voxel Print takes PNG layers");
  if (p.layerDigits != 1) v.fail("image.layer_digits", "expected 1: GrabCAD Voxel Print layers are numbered without padding");
  if (p.buildFileName != "ConfigFile.xml") v.fail("build_file.name", "expected \"ConfigFile.xml\", the name GrabCAD Voxel Print reads");
  if (p.supportPolicy != SupportPolicy::Printer)
    v.fail("support.policy", "expected \"printer\": GrabCAD Voxel Print adds the support itself");
  std::set<std::array<unsigned char, 4>> colours = {p.gcvf.backgroundRgba};
  int used = 1;
  for (std::size_t i = 0; i < p.materials.size(); ++i) {
    const ProfileMaterial& m = p.materials[i];
    if (m.role == MaterialRole::Support) continue;
    ++used;
    if (!colours.insert(m.rgba).second)
      v.fail(memberPath(indexPath("materials", i), "rgba"), "expected a colour of its own (not the background's or another material's): "
                                                    "each colour in a GrabCAD Voxel Print image is one material");
  }
  if (used > p.gcvf.maxNumberOfColors)
    v.fail("gcvf.max_number_of_colors", "the profile uses " + std::to_string(used) + " colours (background included)");
}

namespace {

void readMaterial(Validator& v, const json& m, const std::string& path, Profile& p, int count[3]) {
  ProfileMaterial pm;
  pm.name = v.fileName(m, path, "name").value_or("");
  if (auto role = v.string(m, path, "role")) {
    if (*role == "rigid") pm.role = MaterialRole::Rigid;
    else if (*role == "rubbery") pm.role = MaterialRole::Rubbery;
    else if (*role == "support") pm.role = MaterialRole::Support;
    else v.fail(memberPath(path, "role"), "expected one of: rigid, rubbery, support; got \"" + *role + "\"");
    count[static_cast<int>(pm.role)]++;
  }
  if (const json* d = v.require(m, path, "density_g_per_ml", "the cured density in g/mL"))
    pm.densityGPerMl = v.real(*d, memberPath(path, "density_g_per_ml"), "a density in g/mL", 0.0, kMaxDensity).value_or(0.0);
  v.array<3>(m, path, "preview_rgb", "colour components 0..255", [&](const json& j, const std::string& cp, std::size_t c) {
    auto value = v.integer(j, cp, "a colour component", 0, 255);
    if (value) pm.previewRgb[c] = static_cast<unsigned char>(*value);
    return value.has_value();
  });
  if (m.contains("rgba") || (p.jobFormat == JobFormat::Gcvf && pm.role != MaterialRole::Support))
    readRgba(v, m, path, "rgba", pm.rgba);
  p.materials.push_back(pm);
}

}  // namespace

void readMaterials(Validator& v, const json& doc, Profile& p) {
  const json* mats = v.require(doc, "", "materials", "an array of materials");
  if (!mats) return;
  if (!mats->is_array()) {
    v.fail("materials", "expected an array of materials, got " + describeJson(*mats));
    return;
  }
  int count[3] = {0, 0, 0};
  for (std::size_t i = 0; i < mats->size() && i < 16; ++i) {
    const json& m = (*mats)[i];
    if (!m.is_object()) v.fail(indexPath("materials", i), "expected an object, got " + describeJson(m));
    else readMaterial(v, m, indexPath("materials", i), p, count);
  }
  if (mats->size() > 16) v.fail("materials", "expected at most 16 materials, got " + std::to_string(mats->size()));
  const char* roles[3] = {"rigid", "rubbery", "support"};
  for (int r = 0; r < 3; ++r)
    if (count[r] != 1)
      v.fail("materials", "expected exactly one material with role \"" + std::string(roles[r]) + "\", found " +
                              std::to_string(count[r]));
  if (p.modelMaterialSlots > 0 && count[0] + count[1] > p.modelMaterialSlots)
    v.fail("materials", "more model materials than the printer's " + std::to_string(p.modelMaterialSlots) + " slots");
}

void readImage(Validator& v, const json& doc, Profile& p) {
  const json* image = v.object(doc, "", "image");
  if (!image) return;
  if (auto format = v.string(*image, "image", "format")) {
    try {
      p.imageFormat = parseImageFormat(*format);
    } catch (const std::invalid_argument&) {
      v.fail("image.format", "expected \"bmp\" or \"png\", got \"" + *format + "\"");
    }
  }
  if (const json* depth = v.require(*image, "image", "bit_depth", "bits per pixel"); depth && *depth != p.imageBitDepth())
    v.fail("image.bit_depth", p.jobFormat == JobFormat::Gcvf
                                  ? "expected 32 (GrabCAD Voxel Print takes 8-bit RGBA images), got " + describeJson(*depth)
                                  : "expected 1 (voxel printing takes 1-bit bitmaps), got " + describeJson(*depth));
  if (const json* a = v.require(*image, "image", "column_alignment", "the column-count multiple"))
    p.columnAlignment = v.integer(*a, "image.column_alignment", "a column multiple", 8, 4096).value_or(32);
  if (p.columnAlignment % 8 != 0) v.fail("image.column_alignment", "expected a multiple of 8 (whole bytes per row)");
  v.array<2>(*image, "image", "padding_voxels", "blank margins (columns, rows)", [&](const json& j, const std::string& path, std::size_t i) {
    auto value = v.integer(j, path, "a margin in voxels", 0, kMaxTrayVoxels);
    if (value) p.paddingVoxels[i] = *value;
    return value.has_value();
  });
  if (const json* d = v.require(*image, "image", "layer_digits", "the zero-padded width of layer numbers"))
    p.layerDigits = v.integer(*d, "image.layer_digits", "a digit count", 1, 9).value_or(4);
  if (auto origin = v.string(*image, "image", "origin"); origin && *origin != "top-left")
    v.fail("image.origin", "expected \"top-left\" (the only origin the emitter writes), got \"" + *origin + "\"");
  p.rowOrder = v.string(*image, "image", "row_order").value_or("");
}

void readRest(Validator& v, const json& doc, Profile& p) {
  v.array<3>(doc, "", "tray_mm", "build tray sizes in mm (x, y, z)", [&](const json& j, const std::string& path, std::size_t i) {
    auto s = v.real(j, path, "a tray size in mm", 0.0, kMaxTrayMm);
    if (s) p.trayMm[i] = *s;
    return s.has_value();
  });
  if (const json* slots = v.require(doc, "", "model_material_slots", "the number of model materials the printer loads"))
    p.modelMaterialSlots = v.integer(*slots, "model_material_slots", "a slot count", 1, 16).value_or(0);
  if (const json* build = v.object(doc, "", "build_file")) {
    p.buildFileName = v.fileName(*build, "build_file", "name").value_or("");
    if (const json* fv = v.require(*build, "build_file", "format_version", "the build file format version"))
      p.buildFormatVersion = v.integer(*fv, "build_file.format_version", "a version", 1, 1000).value_or(1);
  }
  if (const json* support = v.object(doc, "", "support")) {
    if (auto policy = v.string(*support, "support", "policy")) {
      try {
        p.supportPolicy = parseSupportPolicy(*policy);
      } catch (const std::invalid_argument&) {
        v.fail("support.policy", "expected \"printer\" or \"explicit\", got \"" + *policy + "\"");
      }
    }
  }
}

// The tray in voxels bounds every image and preview a job of this profile can have.
void checkTrayVoxels(Validator& v, const Profile& p) {
  if (p.trayMm[0] <= 0.0 || p.voxelSizeMm[0] <= 0.0 || p.trayMm[1] <= 0.0 || p.voxelSizeMm[1] <= 0.0 ||
      p.trayMm[2] <= 0.0 || p.voxelSizeMm[2] <= 0.0)
    return;  // already reported
  const char* what[3] = {"image columns (x)", "image rows (y)", "layers (z)"};
  std::array<double, 3> voxels{};
  bool ok = true;
  for (int a = 0; a < 3; ++a) {
    voxels[a] = std::floor(p.trayMm[a] / p.voxelSizeMm[a]);
    if (voxels[a] > kMaxTrayVoxels) {
      v.fail(indexPath("tray_mm", a), "the tray holds " + number(voxels[a]) + " " + what[a] + " of " + number(p.voxelSizeMm[a]) +
                                      " mm; expected at most " + std::to_string(kMaxTrayVoxels));
      ok = false;
    }
  }
  // Other print modes: their layers too must be countable (a part is checked against the preview
  // limits when its job is planned).
  for (std::size_t m = 0; m < p.printModes.size(); ++m)
    if (p.printModes[m].layerThicknessMm > 0 && std::floor(p.trayMm[2] / p.printModes[m].layerThicknessMm) > kMaxTrayVoxels)
      v.fail(memberPath(indexPath("resolution.print_modes", m), "layer_thickness_mm"),
             "the tray holds more than " + std::to_string(kMaxTrayVoxels) + " layers of it");
  // Layer numbers are padded to image.layer_digits, the width the build file declares to the printer: a
  // full tray's layers must fit it (1 digit wrote _0 .. _49 under a declared _x).
  if (p.jobFormat != JobFormat::Gcvf) {
    double layers = voxels[2];
    for (const PrintMode& m : p.printModes)
      if (m.layerThicknessMm > 0) layers = std::max(layers, std::floor(p.trayMm[2] / m.layerThicknessMm));
    const std::size_t digits = std::to_string(static_cast<long long>(std::max(layers, 1.0)) - 1).size();
    if (layers <= kMaxTrayVoxels && digits > static_cast<std::size_t>(p.layerDigits))
      v.fail("image.layer_digits", "expected at least " + std::to_string(digits) + ": the tray holds up to " + number(layers) +
                                       " layers, numbered from 0 in names as wide as the build file declares");
  }
  const char* faces[3] = {"a layer image (columns x rows)", "the front preview (columns x layers)", "the side preview (rows x layers)"};
  const double pixels[3] = {voxels[0] * voxels[1], voxels[0] * voxels[2], voxels[1] * voxels[2]};
  for (int f = 0; f < 3 && ok; ++f)
    if (pixels[f] > static_cast<double>(kMaxTrayFacePixels))
      v.fail("tray_mm", std::string("a full tray makes ") + faces[f] + " of " + number(pixels[f]) + " pixels; expected at most " +
                            std::to_string(kMaxTrayFacePixels));
  for (int a = 0; a < 2 && ok; ++a)
    if (2.0 * p.paddingVoxels[a] + 1.0 > voxels[a])
      v.fail(indexPath("image.padding_voxels", a), "expected at most " + number(std::max(0.0, std::floor((voxels[a] - 1) / 2))) +
                                                   " voxels: a one-voxel part with this margin on both sides must fit the tray's " +
                                                   number(voxels[a]) + " " + what[a]);
}

// Every file a job holds must have a name of its own on case-insensitive file systems too.
void checkNamesUnique(Validator& v, const Profile& p) {
  // manifest.json, report.html and previews/ are the job writer's own names.
  std::map<std::string, std::string> taken = {
      {kManifestName, "the job manifest"}, {kReportName, "the job report"}, {"previews", "the previews folder"}};
  if (!p.buildFileName.empty())
    if (auto [at, fresh] = taken.emplace(lower(p.buildFileName), "build_file.name"); !fresh)
      v.fail("build_file.name", "\"" + p.buildFileName + "\" is the name of " + at->second +
                                    " on a case-insensitive file system (Windows, macOS)");
  for (std::size_t i = 0; i < p.materials.size(); ++i) {
    const std::string& name = p.materials[i].name;
    if (name.empty()) continue;
    const std::string path = memberPath(indexPath("materials", i), "name");
    if (auto [at, fresh] = taken.emplace(lower(name), path); !fresh)
      v.fail(path, "\"" + name + "\" is the same name as " + at->second +
                       " on a case-insensitive file system (Windows, macOS); expected names that differ in more than case");
    // A build file such as "vero_0001.bmp" would be overwritten by a layer image.
    const std::string stem = lower(name) + "_", build = lower(p.buildFileName);
    if (build.starts_with(stem)) {
      const std::string rest = build.substr(stem.size());
      const std::size_t dot = rest.find('.');
      if (dot != std::string::npos && dot > 0 && rest.find_first_not_of("0123456789") == dot &&
          (rest.substr(dot) == ".bmp" || rest.substr(dot) == ".png"))
        v.fail("build_file.name", "\"" + p.buildFileName + "\" is the name of a layer image of " + name);
    }
  }
}

}  // namespace rodfab::printer_profiles::detail
