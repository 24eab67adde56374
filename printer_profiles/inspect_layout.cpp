// The layout a job must have, from its printer profile and the manifest's numbers the profile bounds
// (image format and size, layer count, support, materials, layers, file table, previews, report): every
// entry with the most bytes it may hold. The frame and statistics blocks are read in
// inspect_manifest_figures.cpp, the manifest's fields through inspect_manifest_fields.hpp.
#include "printer_profiles/inspect_layout.hpp"

#include "printer_profiles/inspect.hpp"
#include "printer_profiles/inspect_manifest_fields.hpp"
#include "printer_profiles/job_reader.hpp"
#include "printer_profiles/job_writer.hpp"

#include "common/json_input.hpp"
#include "common/sha256.hpp"
#include "common/xxh128.hpp"

#include <algorithm>
#include <cmath>

namespace rodfab::printer_profiles {

using nlohmann::json;

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

// ------------------------------------------------------------------------------------------ manifest

namespace {

const char* kProjectionsMaterial = "previews/projections-material.png";
const char* kProjectionsModulus = "previews/projections-modulus.png";
const char* kContactSheet = "previews/contact-sheet.png";

using common::indexPath;
using common::memberPath;
using manifest_input::describe;
using manifest_input::Fields;
using manifest_input::nearlyEqual;
using manifest_input::readFrame;
using manifest_input::readStatistics;

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

// The fields that restate the profile or describe the images, checked where present (the writer always
// writes them; the fuzz target's seeds leave them out): each must say what the profile and the writer
// say, as a reader of the manifest alone would take them (a wrong pixels-per-metre or tray, a bogus
// printer) even though the images do not depend on them.
void checkDescriptions(const json& m, const Profile& p, Fields& f) {
  const auto present = [](const json& block, const char* key) { return block.is_object() && block.contains(key); };
  if (const auto b = m.find("profile"); b != m.end() && b->is_object()) {
    if (present(*b, "printer")) f.same(*b, "profile", "printer", p.printer, "the profile's printer");
    if (present(*b, "tray_mm"))
      if (const auto v = f.vec3(*b, "profile", "tray_mm"); v)
        for (int a = 0; a < 3; ++a)
          if (!nearlyEqual((*v)[a], p.trayMm[a])) f.fail(indexPath("profile.tray_mm", a), "expected " + describe(json(p.trayMm[a])) + " mm, the profile's");
    if (present(*b, "layer_thickness_mm"))
      if (const auto t = f.number(*b, "profile", "layer_thickness_mm"); t && !nearlyEqual(*t, p.layerThicknessMm()))
        f.fail("profile.layer_thickness_mm", "expected " + describe(json(p.layerThicknessMm())) + " mm, the profile's");
  }
  if (const auto b = m.find("image"); b != m.end() && b->is_object()) {
    const char* key[2] = {"x_pixels_per_metre", "y_pixels_per_metre"};
    const int dpi[2] = {p.xDpi, p.yDpi};
    for (int a = 0; a < 2; ++a)
      if (present(*b, key[a]))
        if (const auto got = f.integer(*b, "image", key[a], 1, 1000000000); got && *got != pixelsPerMetre(dpi[a]))
          f.fail(std::string("image.") + key[a], "expected " + std::to_string(pixelsPerMetre(dpi[a])) + " (" + std::to_string(dpi[a]) + " dpi)");
    if (present(*b, "origin")) f.same(*b, "image", "origin", "top-left", "where the writer's first row and column are");
    if (present(*b, "row_order")) f.same(*b, "image", "row_order", p.rowOrder, "the profile's row order");
  }
}

// The calibration the moduli were mapped with (null when none was): its file's name and SHA-256, the
// materials it was measured on and its warning, where present.
void readCalibration(const json& m, Fields& f) {
  const auto c = m.find("calibration");
  if (c == m.end() || c->is_null()) return;
  if (!c->is_object()) return f.wrong("calibration", "an object or null", *c);
  f.string(*c, "calibration", "file");
  if (const auto sha = f.string(*c, "calibration", "sha256"); sha && !common::isSha256Hex(*sha))
    f.fail("calibration.sha256", "expected 64 lowercase hexadecimal digits, got " + describe(json(*sha)));
  if (const auto materials = c->find("materials"); materials != c->end() && !materials->is_null()) {
    if (!materials->is_object()) return f.wrong("calibration.materials", "an object or null", *materials);
    f.string(*materials, "calibration.materials", "rigid");
    f.string(*materials, "calibration.materials", "rubbery");
  }
  if (const auto warning = c->find("warning"); warning != c->end() && !warning->is_null() && !warning->is_string())
    f.wrong("calibration.warning", "a string or null", *warning);
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
  const auto ditherer = f.string(*d, "dithering", "ditherer");
  if (ditherer && !isDithererLabel(*ditherer))
    f.fail("dithering.ditherer", "expected up to 64 lowercase letters, digits and '-', got " + describe(json(*ditherer)));
  s.ditherer = printableName(ditherer.value_or(""));
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
  checkDescriptions(m, p, f);
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
  readCalibration(m, f);
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
