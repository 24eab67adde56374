#include "printer_profiles/profile.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>

namespace rodfab::printer_profiles {

using nlohmann::json;

const char* toString(MaterialRole role) {
  switch (role) {
    case MaterialRole::Rigid: return "rigid";
    case MaterialRole::Rubbery: return "rubbery";
    case MaterialRole::Support: return "support";
  }
  return "?";
}

const char* toString(ImageFormat format) { return format == ImageFormat::Bmp ? "bmp" : "png"; }

ImageFormat parseImageFormat(const std::string& text) {
  if (text == "bmp") return ImageFormat::Bmp;
  if (text == "png") return ImageFormat::Png;
  throw std::invalid_argument("image format '" + text + "' is not one of: bmp, png");
}

const char* toString(SupportPolicy policy) { return policy == SupportPolicy::Printer ? "printer" : "explicit"; }

SupportPolicy parseSupportPolicy(const std::string& text) {
  if (text == "printer") return SupportPolicy::Printer;
  if (text == "explicit") return SupportPolicy::Explicit;
  throw std::invalid_argument("support policy '" + text + "' is not one of: printer, explicit");
}

const ProfileMaterial& Profile::material(MaterialRole role) const {
  for (const ProfileMaterial& m : materials)
    if (m.role == role) return m;
  throw std::logic_error(std::string("profile ") + name + " has no " + toString(role) + " material");
}

std::string Profile::layerFileName(const ProfileMaterial& m, int layer, ImageFormat format) const {
  std::string number = std::to_string(layer);
  if (static_cast<int>(number.size()) < layerDigits) number.insert(0, layerDigits - number.size(), '0');
  return m.name + "_" + number + "." + toString(format);
}

std::string Profile::layerFilePattern(const ProfileMaterial& m, ImageFormat format) const {
  return m.name + "_" + std::string(layerDigits, 'x') + "." + toString(format);
}

namespace {

std::string formatIssues(const std::string& file, const std::vector<ProfileIssue>& issues) {
  std::ostringstream out;
  for (std::size_t i = 0; i < issues.size(); ++i) {
    if (i) out << '\n';
    out << file << ": ";
    if (!issues[i].path.empty()) out << issues[i].path << ": ";
    out << issues[i].message;
  }
  return out.str();
}

std::string describe(const json& j) {
  std::string s = j.dump();
  if (s.size() > 40) s = s.substr(0, 37) + "...";
  return s;
}

std::string member(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }
std::string index(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

// Collects every violation; each accessor returns what it could read so later checks can go on.
class Validator {
public:
  std::vector<ProfileIssue> issues;

  void fail(const std::string& path, const std::string& message) { issues.push_back({path, message}); }

  const json* object(const json& parent, const std::string& path, const std::string& key) {
    const json* j = require(parent, path, key, "an object");
    if (j && !j->is_object()) {
      fail(member(path, key), "expected an object, got " + describe(*j));
      return nullptr;
    }
    return j;
  }

  const json* require(const json& parent, const std::string& path, const std::string& key, const std::string& what) {
    auto it = parent.find(key);
    if (it == parent.end()) {
      fail(member(path, key), "missing; expected " + what);
      return nullptr;
    }
    return &*it;
  }

  std::optional<std::string> string(const json& parent, const std::string& path, const std::string& key) {
    const json* j = require(parent, path, key, "a string");
    if (!j) return std::nullopt;
    if (!j->is_string() || j->get<std::string>().empty()) {
      fail(member(path, key), "expected a non-empty string, got " + describe(*j));
      return std::nullopt;
    }
    return j->get<std::string>();
  }

  std::optional<double> positive(const json& j, const std::string& path, const std::string& what) {
    if (!j.is_number() || !std::isfinite(j.get<double>()) || !(j.get<double>() > 0.0)) {
      fail(path, "expected " + what + " (a number > 0), got " + describe(j));
      return std::nullopt;
    }
    return j.get<double>();
  }

  std::optional<int> integer(const json& j, const std::string& path, const std::string& what, int lo, int hi) {
    if (!j.is_number_integer() || j.get<long long>() < lo || j.get<long long>() > hi) {
      fail(path, "expected " + what + " (an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + "), got " +
                     describe(j));
      return std::nullopt;
    }
    return static_cast<int>(j.get<long long>());
  }

  template <std::size_t N, typename Read>
  bool array(const json& parent, const std::string& path, const std::string& key, const std::string& what, Read read) {
    const json* j = require(parent, path, key, "an array of " + std::to_string(N) + " " + what);
    if (!j) return false;
    const std::string p = member(path, key);
    if (!j->is_array() || j->size() != N) {
      fail(p, "expected an array of " + std::to_string(N) + " " + what + ", got " + describe(*j));
      return false;
    }
    bool ok = true;
    for (std::size_t i = 0; i < N; ++i) ok = read((*j)[i], index(p, i), i) && ok;
    return ok;
  }
};

}  // namespace

ProfileError::ProfileError(std::string file, std::vector<ProfileIssue> issues)
    : std::runtime_error(formatIssues(file, issues)), file_(std::move(file)), issues_(std::move(issues)) {}

Profile parseProfile(const std::string& text, const std::string& sourceName) {
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {  // parse_error, or out_of_range for a number too large (1e400)
    throw ProfileError(sourceName, {{"", std::string("not valid JSON: ") + e.what()}});
  }
  Validator v;
  if (!doc.is_object()) throw ProfileError(sourceName, {{"", "expected a JSON object at the top level"}});

  Profile p;
  p.source = sourceName;
  if (auto format = v.string(doc, "", "format"); format && *format != kProfileFormat)
    v.fail("format", "expected \"" + std::string(kProfileFormat) + "\", got \"" + *format + "\"");
  p.name = v.string(doc, "", "name").value_or("");
  p.printer = v.string(doc, "", "printer").value_or("");
  if (auto it = doc.find("description"); it != doc.end() && it->is_string()) p.description = it->get<std::string>();

  if (const json* res = v.object(doc, "", "resolution")) {
    p.xDpi = v.require(*res, "resolution", "x_dpi", "dots per inch along x (image columns)")
                 ? v.integer((*res)["x_dpi"], "resolution.x_dpi", "dots per inch along x", 1, 100000).value_or(0)
                 : 0;
    p.yDpi = v.require(*res, "resolution", "y_dpi", "dots per inch along y (image rows)")
                 ? v.integer((*res)["y_dpi"], "resolution.y_dpi", "dots per inch along y", 1, 100000).value_or(0)
                 : 0;
    std::optional<double> layer;
    if (const json* t = v.require(*res, "resolution", "layer_thickness_mm", "the layer thickness in mm"))
      layer = v.positive(*t, "resolution.layer_thickness_mm", "a layer thickness in mm");
    const bool sizesOk = v.array<3>(*res, "resolution", "voxel_size_mm", "voxel sizes in mm (x, y, z)",
                                    [&](const json& j, const std::string& path, std::size_t i) {
                                      auto s = v.positive(j, path, "a voxel size in mm");
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
        v.fail(index("resolution.voxel_size_mm", a), msg.str());
      }
    }
    if (sizesOk && layer && std::abs(*layer - p.voxelSizeMm[2]) > 1e-9)
      v.fail("resolution.voxel_size_mm[2]", "expected the layer thickness " + std::to_string(*layer) + " mm");
  }

  v.array<3>(doc, "", "tray_mm", "build tray sizes in mm (x, y, z)", [&](const json& j, const std::string& path, std::size_t i) {
    auto s = v.positive(j, path, "a tray size in mm");
    if (s) p.trayMm[i] = *s;
    return s.has_value();
  });
  if (const json* slots = v.require(doc, "", "model_material_slots", "the number of model materials the printer loads"))
    p.modelMaterialSlots = v.integer(*slots, "model_material_slots", "a slot count", 1, 16).value_or(0);

  if (const json* mats = v.require(doc, "", "materials", "an array of materials")) {
    if (!mats->is_array()) {
      v.fail("materials", "expected an array of materials, got " + describe(*mats));
    } else {
      std::set<std::string> names;
      int count[3] = {0, 0, 0};
      for (std::size_t i = 0; i < mats->size(); ++i) {
        const json& m = (*mats)[i];
        const std::string path = index("materials", i);
        if (!m.is_object()) {
          v.fail(path, "expected an object, got " + describe(m));
          continue;
        }
        ProfileMaterial pm;
        pm.name = v.string(m, path, "name").value_or("");
        if (!pm.name.empty()) {
          if (!names.insert(pm.name).second) v.fail(member(path, "name"), "duplicate material name \"" + pm.name + "\"");
          if (pm.name.find_first_of("/\\:*?\"<>| ") != std::string::npos)
            v.fail(member(path, "name"), "expected a name usable in file names (no spaces or /\\:*?\"<>|)");
        }
        if (auto role = v.string(m, path, "role")) {
          if (*role == "rigid") pm.role = MaterialRole::Rigid;
          else if (*role == "rubbery") pm.role = MaterialRole::Rubbery;
          else if (*role == "support") pm.role = MaterialRole::Support;
          else v.fail(member(path, "role"), "expected one of: rigid, rubbery, support; got \"" + *role + "\"");
          count[static_cast<int>(pm.role)]++;
        }
        if (const json* d = v.require(m, path, "density_g_per_ml", "the cured density in g/mL"))
          pm.densityGPerMl = v.positive(*d, member(path, "density_g_per_ml"), "a density in g/mL").value_or(0.0);
        v.array<3>(m, path, "preview_rgb", "colour components 0..255", [&](const json& j, const std::string& cp, std::size_t c) {
          auto value = v.integer(j, cp, "a colour component", 0, 255);
          if (value) pm.previewRgb[c] = static_cast<unsigned char>(*value);
          return value.has_value();
        });
        p.materials.push_back(pm);
      }
      const char* roles[3] = {"rigid", "rubbery", "support"};
      for (int r = 0; r < 3; ++r)
        if (count[r] != 1)
          v.fail("materials", "expected exactly one material with role \"" + std::string(roles[r]) + "\", found " +
                                  std::to_string(count[r]));
      if (p.modelMaterialSlots > 0 && count[0] + count[1] > p.modelMaterialSlots)
        v.fail("materials", "more model materials than the printer's " + std::to_string(p.modelMaterialSlots) + " slots");
    }
  }

  if (const json* image = v.object(doc, "", "image")) {
    if (auto format = v.string(*image, "image", "format")) {
      try {
        p.imageFormat = parseImageFormat(*format);
      } catch (const std::invalid_argument&) {
        v.fail("image.format", "expected \"bmp\" or \"png\", got \"" + *format + "\"");
      }
    }
    if (const json* depth = v.require(*image, "image", "bit_depth", "1 (one bit per pixel)"); depth && *depth != 1)
      v.fail("image.bit_depth", "expected 1 (voxel printing takes 1-bit bitmaps), got " + describe(*depth));
    if (const json* a = v.require(*image, "image", "column_alignment", "the column-count multiple"))
      p.columnAlignment = v.integer(*a, "image.column_alignment", "a column multiple", 8, 4096).value_or(32);
    if (p.columnAlignment % 8 != 0) v.fail("image.column_alignment", "expected a multiple of 8 (whole bytes per row)");
    v.array<2>(*image, "image", "padding_voxels", "blank margins (columns, rows)", [&](const json& j, const std::string& path, std::size_t i) {
      auto value = v.integer(j, path, "a margin in voxels", 0, 100000);
      if (value) p.paddingVoxels[i] = *value;
      return value.has_value();
    });
    if (const json* d = v.require(*image, "image", "layer_digits", "the zero-padded width of layer numbers"))
      p.layerDigits = v.integer(*d, "image.layer_digits", "a digit count", 1, 9).value_or(4);
    if (auto origin = v.string(*image, "image", "origin"); origin && *origin != "top-left")
      v.fail("image.origin", "expected \"top-left\" (the only origin the emitter writes), got \"" + *origin + "\"");
    p.rowOrder = v.string(*image, "image", "row_order").value_or("");
  }

  if (const json* build = v.object(doc, "", "build_file")) {
    p.buildFileName = v.string(*build, "build_file", "name").value_or("");
    if (p.buildFileName.find('/') != std::string::npos) v.fail("build_file.name", "expected a plain file name");
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

  if (!v.issues.empty()) throw ProfileError(sourceName, v.issues);
  return p;
}

Profile readProfile(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ProfileError(file.string(), {{"", "cannot open the profile file"}});
  std::ostringstream text;
  text << in.rdbuf();
  Profile p = parseProfile(text.str(), file.string());
  p.source = file;
  return p;
}

std::filesystem::path bundledProfileDir() {
  if (const char* dir = std::getenv("RODFAB_PROFILE_DIR"); dir && *dir) return dir;
  return std::filesystem::path(RODFAB_SOURCE_DIR) / "printer_profiles";
}

std::vector<std::string> bundledProfileNames() {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(bundledProfileDir(), ec))
    if (entry.is_regular_file() && entry.path().extension() == ".json") names.push_back(entry.path().stem().string());
  std::sort(names.begin(), names.end());
  return names;
}

Profile loadProfile(const std::string& nameOrPath) {
  const bool isName = nameOrPath.find('/') == std::string::npos && !nameOrPath.ends_with(".json");
  if (!isName) return readProfile(nameOrPath);
  const std::filesystem::path file = bundledProfileDir() / (nameOrPath + ".json");
  if (!std::filesystem::exists(file)) {
    std::string list;
    for (const std::string& n : bundledProfileNames()) list += (list.empty() ? "" : ", ") + n;
    throw ProfileError(nameOrPath, {{"", "no bundled profile of that name in " + bundledProfileDir().string() +
                                             " (bundled: " + (list.empty() ? "none" : list) +
                                             "); give a path to use another profile file"}});
  }
  Profile p = readProfile(file);
  if (p.name != nameOrPath)
    throw ProfileError(file.string(), {{"name", "expected \"" + nameOrPath + "\" (the file name), got \"" + p.name + "\""}});
  return p;
}

}  // namespace rodfab::printer_profiles
