#include "printer_profiles/inspect_layout.hpp"

#include "printer_profiles/inspect.hpp"
#include "printer_profiles/job_reader.hpp"
#include "printer_profiles/job_writer.hpp"

#include "common/json_input.hpp"
#include "common/sha256.hpp"
#include "common/xxh128.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rodfab::printer_profiles {

using nlohmann::json;

// ------------------------------------------------------------------------------------------ findings

void Findings::push(std::string text) {
  if (list_.size() < kMaxDefects) list_.push_back(std::move(text));
  else ++dropped_;
}

void Findings::at(const std::string& entry, const std::string& message) {
  push(job_ + ": " + printableName(entry) + ": " + message);
}

void Findings::whole(const std::string& message) { push(job_ + ": " + message); }

void Findings::located(const std::string& message) { push(message); }

void Findings::merge(const Findings& other) {
  for (const std::string& s : other.list_) push(s);
  dropped_ += other.dropped_;
}

std::vector<std::string> Findings::take() {
  std::vector<std::string> out = std::move(list_);
  if (dropped_) out.push_back(job_ + ": ... and " + std::to_string(dropped_) + " more defects");
  list_.clear();
  dropped_ = 0;
  return out;
}

// ------------------------------------------------------------------------------------------ limits

ProfileLimits limitsOf(const Profile& p) {
  // planJob refuses images wider or taller than the tray, and parts taller than it.
  const auto fit = [](double trayMm, double voxelMm) {
    return voxelMm > 0 ? static_cast<int>(std::min(std::floor(trayMm / voxelMm + 1e-6), 1e8)) : 0;
  };
  ProfileLimits l;
  const int align = std::max(1, p.columnAlignment);
  l.maxWidth = fit(p.trayMm[0], p.voxelSizeMm[0]) / align * align;
  l.maxHeight = fit(p.trayMm[1], p.voxelSizeMm[1]);
  l.maxLayers = fit(p.trayMm[2], p.voxelSizeMm[2]);
  const auto layers = static_cast<std::size_t>(l.maxLayers);
  l.maxEntries = layers * 3 + 16 + 256;  // three stacks, manifest, build file, previews; some extras to report
  l.maxManifestBytes = (4u << 20) + static_cast<std::uint64_t>(layers) * 2048;
  l.maxManifestValues = 65536 + layers * 64;
  return l;
}

std::uint64_t pngMaxBytes(std::uint64_t rawBytes) { return rawBytes + rawBytes / 64 + (64u << 10); }

// ------------------------------------------------------------------------------------------ JSON

namespace {

// A message parseJsonStrict made printable (it escapes what it quotes: controls, bytes that are not
// UTF-8, the backslash) in inspect's form, plain ASCII: the UTF-8 characters it kept as \xNN too.
// Not printableName, which would escape those escapes' backslashes a second time.
std::string asciiOnly(const std::string& printable) {
  std::string out;
  for (const char ch : printable) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c < 0x7f) {
      out += ch;
      continue;
    }
    char buf[8];
    std::snprintf(buf, sizeof buf, "\\x%02x", c);
    out += buf;
  }
  return out;
}

}  // namespace

json parseUntrustedJson(std::span<const std::uint8_t> text, std::size_t maxValues) {
  try {
    return common::parseJsonStrict(std::string(text.begin(), text.end()), common::kMaxJsonDepth, maxValues);
  } catch (const common::JsonInputError& e) {
    // The message first: a path 64 levels deep would hide it.
    std::size_t cut = 57;  // not inside a UTF-8 character
    while (e.path.size() > 60 && cut > 0 && (static_cast<unsigned char>(e.path[cut]) & 0xc0) == 0x80) --cut;
    const std::string where = e.path.size() > 60 ? e.path.substr(0, cut) + "..." : e.path;
    throw std::runtime_error(asciiOnly(e.message + (where.empty() ? "" : " (at " + where + ")")));
  } catch (const json::exception& e) {  // a number beyond a double
    throw std::runtime_error("not JSON (" + asciiOnly(common::printableJsonError(e.what())) + ")");
  }
}

// ------------------------------------------------------------------------------------------ manifest

namespace {

const char* kProjectionsMaterial = "previews/projections-material.png";
const char* kProjectionsModulus = "previews/projections-modulus.png";
const char* kContactSheet = "previews/contact-sheet.png";

// A short description of an untrusted value, for messages: never serializes containers.
std::string describe(const json& j) {
  if (j.is_string()) {
    const std::string& s = j.get_ref<const std::string&>();
    return "\"" + printableName(s.size() > 60 ? s.substr(0, 57) + "..." : s) + "\"";
  }
  if (j.is_number_integer() || j.is_number_unsigned() || j.is_boolean()) return j.dump();  // scalars only
  if (j.is_number_float()) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.9g", j.get<double>());
    return buf;
  }
  return std::string("a") + (j.is_object() || j.is_array() ? "n " : " ") + j.type_name();
}

using common::indexPath;
using common::memberPath;

// Typed access to manifest fields; each failure is a finding at "manifest.json: PATH".
class Fields {
public:
  explicit Fields(Findings& findings) : findings_(findings) {}

  void fail(const std::string& path, const std::string& message) { findings_.at(kManifestName, path + ": " + message); }

  const json* get(const json& parent, const std::string& path, const std::string& key, const char* what) {
    const auto it = parent.is_object() ? parent.find(key) : parent.end();
    if (it == parent.end()) {
      fail(memberPath(path, key), std::string("missing; expected ") + what);
      return nullptr;
    }
    return &*it;
  }
  // parent[key] when `isKind` holds for it (`what`: "an object", ...); nullptr after an issue.
  const json* ofKind(const json& parent, const std::string& path, const std::string& key, const char* what,
                     bool (json::*isKind)() const noexcept) {
    const json* j = get(parent, path, key, what);
    if (j && !(j->*isKind)()) {
      wrong(memberPath(path, key), what, *j);
      return nullptr;
    }
    return j;
  }
  const json* object(const json& parent, const std::string& path, const std::string& key) {
    return ofKind(parent, path, key, "an object", &json::is_object);
  }
  const json* array(const json& parent, const std::string& path, const std::string& key) {
    return ofKind(parent, path, key, "an array", &json::is_array);
  }
  std::optional<std::string> string(const json& parent, const std::string& path, const std::string& key) {
    const json* j = get(parent, path, key, "a string");
    if (!j) return std::nullopt;
    if (!j->is_string()) {
      wrong(memberPath(path, key), "a string", *j);
      return std::nullopt;
    }
    return j->get<std::string>();
  }
  std::optional<std::int64_t> integer(const json& j, const std::string& path, std::int64_t lo, std::int64_t hi) {
    const bool inRange = (j.is_number_integer() && j.get<std::int64_t>() >= lo && j.get<std::int64_t>() <= hi) ||
                         (j.is_number_unsigned() && j.get<std::uint64_t>() <= static_cast<std::uint64_t>(hi) && lo <= 0);
    if (!inRange) {
      fail(path, "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + describe(j));
      return std::nullopt;
    }
    return j.get<std::int64_t>();
  }
  std::optional<std::int64_t> integer(const json& parent, const std::string& path, const std::string& key, std::int64_t lo,
                                      std::int64_t hi) {
    const json* j = get(parent, path, key, "an integer");
    return j ? integer(*j, memberPath(path, key), lo, hi) : std::nullopt;
  }
  std::optional<std::uint64_t> count(const json& j, const std::string& path) {
    if (!j.is_number_unsigned() && !(j.is_number_integer() && j.get<std::int64_t>() >= 0)) {
      fail(path, "expected a whole number >= 0, got " + describe(j));
      return std::nullopt;
    }
    return j.get<std::uint64_t>();
  }
  std::optional<double> number(const json& parent, const std::string& path, const std::string& key) {
    const json* j = get(parent, path, key, "a number");
    if (!j) return std::nullopt;
    if (!j->is_number() || !std::isfinite(j->get<double>())) {
      wrong(memberPath(path, key), "a finite number", *j);
      return std::nullopt;
    }
    return j->get<double>();
  }
  std::optional<std::array<double, 3>> vec3(const json& parent, const std::string& path, const std::string& key) {
    const json* j = get(parent, path, key, "three numbers");
    if (!j) return std::nullopt;
    if (!j->is_array() || j->size() != 3 || !std::all_of(j->begin(), j->end(), [](const json& v) {
          return v.is_number() && std::isfinite(v.get<double>());
        })) {
      wrong(memberPath(path, key), "an array of three finite numbers", *j);
      return std::nullopt;
    }
    return std::array<double, 3>{(*j)[0].get<double>(), (*j)[1].get<double>(), (*j)[2].get<double>()};
  }
  // `key` must hold exactly `want` (a string).
  void same(const json& parent, const std::string& path, const std::string& key, const std::string& want, const std::string& why) {
    if (const auto got = string(parent, path, key); got && *got != want)
      fail(memberPath(path, key), "expected \"" + printableName(want) + "\" (" + why + "), got " + describe(json(*got)));
  }

private:
  void wrong(const std::string& path, const char* what, const json& got) {
    fail(path, std::string("expected ") + what + ", got " + describe(got));
  }
  Findings& findings_;
};

bool nearlyEqual(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max({1.0, std::abs(a), std::abs(b)}); }

// The manifest's "profile" block must restate the profile: a mismatch means the images were made for
// other numbers (x and y dpi swapped print the part at twice or half its size on a printer, such as
// the Connex3, whose two differ).
void checkProfileBlock(const json& m, const Profile& p, Fields& f) {
  const json* block = f.object(m, "", "profile");
  if (!block) return;
  f.same(*block, "profile", "name", p.name, "the profile the job is checked against");
  const char* axis[2] = {"x", "y"};
  const int dpi[2] = {p.xDpi, p.yDpi};
  for (int a = 0; a < 2; ++a) {
    const std::string key = std::string(axis[a]) + "_dpi";
    if (const auto got = f.integer(*block, "profile", key, 1, 1000000); got && *got != dpi[a])
      f.fail("profile." + key, std::to_string(*got) + ", but the " + p.name + " profile is " + std::to_string(dpi[a]) +
                                   " dpi along " + axis[a] + " (x is the image columns): the part would print at the wrong size" +
                                   (*got == dpi[1 - a] ? " (" + std::to_string(dpi[0]) + "/" + std::to_string(dpi[1]) + " dpi swapped?)" : ""));
  }
  if (const auto v = f.vec3(*block, "profile", "voxel_size_mm"); v)
    for (int a = 0; a < 3; ++a)
      if (!nearlyEqual((*v)[a], p.voxelSizeMm[a]))
        f.fail(indexPath("profile.voxel_size_mm", a), "expected " + describe(json(p.voxelSizeMm[a])) + " mm, the profile's");
  if (const auto got = f.integer(*block, "profile", "column_alignment", 1, 1 << 20); got && *got != p.columnAlignment)
    f.fail("profile.column_alignment", "expected " + std::to_string(p.columnAlignment) + ", the profile's");
}

// Image format and size, layer count, support policy: the numbers the layout is built from.
bool readShape(const json& m, const Profile& p, const ProfileLimits& limits, JobLayout& out, Fields& f, InspectSummary& s) {
  bool ok = true;
  const json* image = f.object(m, "", "image");
  if (!image) return false;
  const auto format = f.string(*image, "image", "format");
  if (format && (*format == "bmp" || *format == "png")) {
    out.imageFormat = parseImageFormat(*format);
    s.imageFormat = *format;
  } else {
    if (format) f.fail("image.format", "expected \"bmp\" or \"png\", got " + describe(json(*format)));
    ok = false;
  }
  const auto width = f.integer(*image, "image", "width", p.columnAlignment, limits.maxWidth);
  if (width && *width % p.columnAlignment != 0)
    f.fail("image.width", std::to_string(*width) + " is not a multiple of the profile's column alignment " +
                              std::to_string(p.columnAlignment));
  const auto height = f.integer(*image, "image", "height", 1, limits.maxHeight);
  const auto layers = f.integer(m, "", "layer_count", 1, limits.maxLayers);
  if (const auto depth = f.integer(*image, "image", "bit_depth", p.imageBitDepth(), p.imageBitDepth()); !depth) ok = false;
  if (!width || *width % p.columnAlignment != 0 || !height || !layers) return false;
  out.width = static_cast<int>(*width);
  out.height = static_cast<int>(*height);
  out.layers = static_cast<int>(*layers);

  const json* support = f.object(m, "", "support");
  const auto policy = support ? f.string(*support, "support", "policy") : std::nullopt;
  if (policy && (*policy == "printer" || *policy == "explicit")) {
    out.support = parseSupportPolicy(*policy);
    s.supportPolicy = *policy;
  } else {
    if (policy) f.fail("support.policy", "expected \"printer\" or \"explicit\", got " + describe(json(*policy)));
    ok = false;
  }
  if (support) f.same(*support, "support", "material", p.material(MaterialRole::Support).name, "the profile's support material");
  return ok;
}

void readPartVoxels(const json& frame, JobLayout& out, Fields& f);
std::optional<MaterialStatistics> readMaterialStatistics(const json& list, const std::string& name, Fields& f);
std::optional<std::uint64_t> readClamped(const json& block, Fields& f);

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

// The materials with bitmap stacks: rigid and rubbery, and support when the job draws it; as the writer
// orders them (by role). The manifest must list exactly those.
void readMaterials(const json& m, const Profile& p, JobLayout& out, Fields& f) {
  for (const MaterialRole role : {MaterialRole::Rigid, MaterialRole::Rubbery, MaterialRole::Support})
    if (role != MaterialRole::Support || out.support == SupportPolicy::Explicit) out.materials.push_back(&p.material(role));
  const json* list = f.array(m, "", "materials");
  if (!list) return;
  if (list->size() != out.materials.size()) {
    f.fail("materials", "lists " + std::to_string(list->size()) + " materials; a job with " + toString(out.support) +
                            " support for " + p.name + " has " + std::to_string(out.materials.size()));
    return;
  }
  for (std::size_t n = 0; n < out.materials.size(); ++n) {
    const json& jm = (*list)[n];
    const std::string path = indexPath("materials", n);
    const ProfileMaterial& want = *out.materials[n];
    if (!jm.is_object()) {
      f.fail(path, "expected an object, got " + describe(jm));
      continue;
    }
    f.same(jm, path, "name", want.name, std::string("the profile's ") + toString(want.role) + " material");
    f.same(jm, path, "role", toString(want.role), "materials are listed rigid, rubbery, support");
    f.same(jm, path, "file_pattern", p.layerFilePattern(want, out.imageFormat), "the profile's naming");
    if (const auto d = f.number(jm, path, "density_g_per_ml"); d && !nearlyEqual(*d, want.densityGPerMl))
      f.fail(memberPath(path, "density_g_per_ml"), "expected " + describe(json(want.densityGPerMl)) + ", the profile's");
  }
}

// One layer's entry of the manifest.
void readLayer(const json& entry, std::size_t l, const Profile& p, JobLayout& out, Fields& f) {
  const std::uint64_t pixels = static_cast<std::uint64_t>(out.width) * static_cast<std::uint64_t>(out.height);
  const std::string path = indexPath("layers", l);
  if (!entry.is_object()) {
    f.fail(path, "expected an object, got " + describe(entry));
    return;
  }
  if (const auto n = f.integer(entry, path, "layer", 0, out.layers); n && *n != static_cast<std::int64_t>(l))
    f.fail(memberPath(path, "layer"), "expected " + std::to_string(l));
  const json* files = f.object(entry, path, "files");
  const json* voxels = f.object(entry, path, "voxels");
  if (files && files->size() != out.materials.size())
    f.fail(memberPath(path, "files"), "names " + std::to_string(files->size()) + " files; expected one per material (" +
                                      std::to_string(out.materials.size()) + ")");
  for (std::size_t n = 0; n < out.materials.size(); ++n) {
    const ProfileMaterial& mat = *out.materials[n];
    if (files) f.same(*files, memberPath(path, "files"), mat.name, p.layerFileName(mat, static_cast<int>(l), out.imageFormat), "the profile's naming");
    const json* v = voxels ? f.get(*voxels, memberPath(path, "voxels"), mat.name, "a voxel count") : nullptr;
    const std::string where = memberPath(memberPath(path, "voxels"), mat.name);
    const auto c = v ? f.count(*v, where) : std::nullopt;
    if (c && *c <= pixels) out.layerVoxels[l][n] = c;
    else if (c) f.fail(where, std::to_string(*c) + " voxels, more than a layer's " + std::to_string(pixels) + " pixels");
  }
}

// Every layer's entry names the expected files and lists a voxel count per material. Problems are
// reported for the first few layers only, then counted: one mistake repeated in every layer is one story.
void readLayers(const json& m, const Profile& p, JobLayout& out, Fields& f, Findings& findings) {
  constexpr std::size_t kLayersReported = 4;
  std::size_t layersWithProblems = 0;
  out.layerVoxels.assign(static_cast<std::size_t>(out.layers), std::vector<std::optional<std::uint64_t>>(out.materials.size()));
  const json* list = f.array(m, "", "layers");
  if (!list) return;
  if (list->size() != static_cast<std::size_t>(out.layers))
    f.fail("layers", "lists " + std::to_string(list->size()) + " layers; layer_count is " + std::to_string(out.layers));
  for (std::size_t l = 0; l < std::min(list->size(), out.layerVoxels.size()); ++l) {
    Findings local = findings.sibling();
    Fields lf(local);
    readLayer((*list)[l], l, p, out, lf);
    if (local.empty()) continue;
    if (++layersWithProblems <= kLayersReported) findings.merge(local);
  }
  if (layersWithProblems > kLayersReported)
    f.fail("layers", "and " + std::to_string(layersWithProblems - kLayersReported) + " more layers with such problems");
}

// A file row's checksum: "xxh128" (32 lowercase hex digits) or, in jobs written before it, "sha256" (64).
// `row` is an object (the caller checks).
std::optional<FileDigest> readFileDigest(const json& row, const std::string& path, Fields& f) {
  const bool xxh = row.contains("xxh128"), sha = row.contains("sha256");
  if (xxh == sha) {
    f.fail(path, xxh ? "holds both \"xxh128\" and \"sha256\"; expected one checksum"
                     : "has no checksum; expected \"xxh128\" (32 lowercase hex digits)");
    return std::nullopt;
  }
  const char* key = xxh ? "xxh128" : "sha256";
  const auto hex = f.string(row, path, key);
  if (!hex) return std::nullopt;
  if (xxh ? !common::isXxh128Hex(*hex) : !common::isSha256Hex(*hex)) {
    f.fail(path + "." + key, std::string("expected ") + (xxh ? "32" : "64") + " lowercase hex digits, got " + describe(json(*hex)));
    return std::nullopt;
  }
  return FileDigest{xxh ? common::HashAlgorithm::Xxh128 : common::HashAlgorithm::Sha256, *hex};
}

void readFileTable(const json& m, JobLayout& out, Fields& f) {
  const json* table = f.object(m, "", "files");
  if (!table) return;
  for (const auto& [name, row] : table->items()) {
    const std::string path = "files." + printableName(name);
    const auto bytes = row.is_object() && row.contains("bytes") ? f.count(row["bytes"], path + ".bytes") : std::nullopt;
    const auto digest = row.is_object() ? readFileDigest(row, path, f) : std::nullopt;
    if (!row.is_object() || !row.contains("bytes")) f.fail(path + ".bytes", "missing; expected the file's size");
    if (bytes && digest) out.listed[name] = {*bytes, *digest};
  }
}

// Previews: the material projections, the modulus ones when the job had moduli, the contact sheet.
// Their pixel sizes are bounded by how previews.cpp lays them out (about 1400 x 1000 views, tiles in a
// 300-pixel box, four per row, one per contact layer).
void readPreviews(const json& m, JobLayout& out, Fields& f) {
  std::size_t contactLayers = static_cast<std::size_t>(out.layers);
  if (const json* list = f.array(m, "", "contact_sheet_layers")) {
    std::int64_t last = -1;
    for (std::size_t n = 0; n < list->size() && n <= contactLayers; ++n)
      if (const auto l = f.integer((*list)[n], indexPath("contact_sheet_layers", n), last + 1, out.layers - 1)) last = *l;
      else break;
    if (list->empty() || list->size() > contactLayers)
      f.fail("contact_sheet_layers", "expected 1 to " + std::to_string(contactLayers) + " layers, got " + std::to_string(list->size()));
    else
      contactLayers = list->size();
  }
  const std::uint64_t projection = pngMaxBytes((3 * 1600 + 1) * 1300ull);
  const std::uint64_t sheetRows = 88 + (contactLayers + 3) / 4 * 340;
  const std::uint64_t sheet = pngMaxBytes((3 * 1344 + 1) * sheetRows);
  const std::vector<std::string> plain = {kProjectionsMaterial, kContactSheet};
  const std::vector<std::string> withModulus = {kProjectionsMaterial, kProjectionsModulus, kContactSheet};
  const json* list = f.array(m, "", "previews");
  std::vector<std::string> names;
  if (list)
    for (const json& n : *list) names.push_back(n.is_string() ? n.get<std::string>() : std::string("\x01"));
  if (list && names != plain && names != withModulus)
    f.fail("previews", std::string("expected [\"") + kProjectionsMaterial + "\", (\"" + kProjectionsModulus + "\",) \"" +
                           kContactSheet + "\"]");
  for (const std::string& name : names == withModulus ? withModulus : plain)
    out.expected[name] = {name == kContactSheet ? EntryRole::ContactSheet : EntryRole::Preview, name == kContactSheet ? sheet : projection};
}

void readOrientation(const json& m, JobLayout& out, Fields& f) {
  out.orientation.assign(out.materials.size(), std::nullopt);
  const json* check = f.object(m, "", "orientation_check");
  if (!check) return;
  for (std::size_t n = 0; n < out.materials.size(); ++n) {
    if (out.materials[n]->role == MaterialRole::Support) continue;  // support has no orientation record
    const std::string path = "orientation_check." + out.materials[n]->name;
    const json* record = f.object(*check, "orientation_check", out.materials[n]->name);
    const json* voxels = record ? f.get(*record, path, "voxels", "a voxel count") : nullptr;
    const auto count = voxels ? f.count(*voxels, path + ".voxels") : std::nullopt;
    if (!count) continue;
    OrientationRecord r{*count, {}, {}, {}};
    if (*count > 0) {
      const auto lo = f.vec3(*record, path, "min_mm"), hi = f.vec3(*record, path, "max_mm"), c = f.vec3(*record, path, "centroid_mm");
      if (!lo || !hi || !c) continue;
      r = {*count, *lo, *hi, *c};
    }
    out.orientation[n] = r;
  }
}

void readDithering(const json& m, Fields& f, InspectSummary& s) {
  const json* d = f.object(m, "", "dithering");
  if (!d) return;
  s.ditherer = printableName(f.string(*d, "dithering", "ditherer").value_or(""));
  if (const json* seed = f.get(*d, "dithering", "seed", "a whole number")) s.seed = f.count(*seed, "dithering.seed");
}

// The job report (report.html, jobs since it was added; older jobs have no "report"): its previews
// embedded in base64 (4 bytes per 3) and a few small pictures and tables.
void readReport(const json& m, JobLayout& out, Fields& f) {
  const auto it = m.find("report");
  if (it == m.end() || it->is_null()) return;
  if (*it != kReportName) {
    f.fail("report", std::string("expected \"") + kReportName + "\" or null, got " + describe(*it));
    return;
  }
  std::uint64_t previews = 0;
  for (const auto& [name, entry] : out.expected)
    if (entry.role == EntryRole::Preview || entry.role == EntryRole::ContactSheet) previews += entry.maxBytes;
  out.expected[kReportName] = {EntryRole::Report, previews / 3 * 4 + (16u << 20)};
}

// Layer images: a BMP is its headers and palette (62 bytes from our writer; other tools' larger headers
// fit the slack) and rows padded to 4 bytes; a PNG at most its filtered rows, barely compressed.
std::uint64_t layerMaxBytes(const JobLayout& l) {
  const auto height = static_cast<std::uint64_t>(l.height);
  if (l.imageFormat == ImageFormat::Bmp) return 1024 + (static_cast<std::uint64_t>(l.width) + 31) / 32 * 4 * height;
  if (l.rgba) return pngMaxBytes((static_cast<std::uint64_t>(l.width) * 4 + 1) * height);  // gcvf: 8-bit RGBA
  return pngMaxBytes(((static_cast<std::uint64_t>(l.width) + 7) / 8 + 1) * height);
}

}  // namespace

std::optional<JobLayout> readLayout(const json& m, const Profile& p, Findings& findings, InspectSummary& s) {
  Fields f(findings);
  if (!m.is_object()) {
    f.fail("(top level)", "expected an object, got " + describe(m));
    return std::nullopt;
  }
  f.same(m, "", "format", kJobFormat, "the job format this rodfab reads");
  checkProfileBlock(m, p, f);
  f.same(m, "", "build_file", p.buildFileName, "the profile's build file");
  JobLayout out;
  out.rgba = p.jobFormat == JobFormat::Gcvf;
  if (!readShape(m, p, limitsOf(p), out, f, s)) return std::nullopt;
  readFrame(m, out, f, s);
  readMaterials(m, p, out, f);
  readLayers(m, p, out, f, findings);
  readFileTable(m, out, f);
  readPreviews(m, out, f);
  readOrientation(m, out, f);
  readStatistics(m, out, f);
  readDithering(m, f, s);
  readReport(m, out, f);

  out.expected[kManifestName] = {EntryRole::Manifest, limitsOf(p).maxManifestBytes};
  out.expected[p.buildFileName] = {EntryRole::BuildFile, 64u << 10};
  const std::uint64_t imageBytes = layerMaxBytes(out);
  for (int l = 0; l < out.layers; ++l)
    for (std::size_t n = 0; n < out.materials.size(); ++n)
      out.expected[p.layerFileName(*out.materials[n], l, out.imageFormat)] = {EntryRole::Layer, imageBytes, l, static_cast<int>(n)};
  return out;
}

}  // namespace rodfab::printer_profiles
