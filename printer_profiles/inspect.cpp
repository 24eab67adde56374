#include "printer_profiles/inspect.hpp"
#include "printer_profiles/gcvf_writer.hpp"
#include "printer_profiles/inspect_gcvf.hpp"

#include "common/sha256.hpp"
#include "printer_profiles/inspect_layout.hpp"
#include "printer_profiles/job_reader.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <set>
#include <sstream>
#include <string_view>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Layers are checked in parallel, but never more at once than their capped images fit in this budget.
constexpr std::uint64_t kLayerMemoryBudget = 512ull << 20;
constexpr int kMaxFolderDepth = 2;  // the job and its previews/ folder; deeper folders are listed, not entered

using common::Sha256;  // files are checked as they stream

// Voxel index sums of one material as decoded from the images, to compare with the manifest's.
// Per byte value: pixels set, and the sum of their positions (0 = most significant bit).
constexpr std::array<std::uint8_t, 256> kBitCounts = [] {
  std::array<std::uint8_t, 256> t{};
  for (int v = 0; v < 256; ++v) t[static_cast<std::size_t>(v)] = static_cast<std::uint8_t>(std::popcount(static_cast<unsigned>(v)));
  return t;
}();
constexpr std::array<std::uint8_t, 256> kBitPositionSums = [] {
  std::array<std::uint8_t, 256> t{};
  for (int v = 0; v < 256; ++v)
    for (int x = 0; x < 8; ++x)
      if ((v >> (7 - x)) & 1) t[static_cast<std::size_t>(v)] = static_cast<std::uint8_t>(t[static_cast<std::size_t>(v)] + x);
  return t;
}();

struct DecodedMoments {
  std::uint64_t count = 0;
  std::array<double, 3> sum{};
  std::array<int, 3> min{INT32_MAX, INT32_MAX, INT32_MAX}, max{INT32_MIN, INT32_MIN, INT32_MIN};
  void add(int j, int k, int n, double sumI, int iMin, int iMax) {
    count += static_cast<std::uint64_t>(n);
    sum[0] += sumI;
    sum[1] += static_cast<double>(n) * j;
    sum[2] += static_cast<double>(n) * k;
    min = {std::min(min[0], iMin), std::min(min[1], j), std::min(min[2], k)};
    max = {std::max(max[0], iMax), std::max(max[1], j), std::max(max[2], k)};
  }
  void merge(const DecodedMoments& o) {
    count += o.count;
    for (int a = 0; a < 3; ++a) {
      sum[a] += o.sum[a];
      min[a] = std::min(min[a], o.min[a]);
      max[a] = std::max(max[a], o.max[a]);
    }
  }
};

struct LayerResult {
  explicit LayerResult(const std::string& job) : findings(job) {}
  Findings findings;
  std::vector<std::uint64_t> voxels;    // per job material
  std::vector<DecodedMoments> moments;  // per job material
};

std::string fmt3(const std::array<double, 3>& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.4f, %.4f, %.4f)", v[0], v[1], v[2]);
  return buf;
}

std::string lowercase(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// `KEY = VALUE;` lines of a build file (no regular expressions: they recurse on long inputs).
std::map<std::string, std::string> buildFileValues(const std::string& text) {
  const auto trim = [](std::string s) {
    const auto first = s.find_first_not_of(" \t\r");
    if (first == std::string::npos) return std::string();
    return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
  };
  std::map<std::string, std::string> values;
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    const std::string line = text.substr(start, end - start);
    start = end + 1;
    const std::size_t eq = line.find('=');
    const std::size_t semi = line.rfind(';');
    if (eq == std::string::npos || semi == std::string::npos || semi < eq) continue;
    values.emplace(trim(line.substr(0, eq)), trim(line.substr(eq + 1, semi - eq - 1)));
  }
  return values;
}

// Reports the first few findings of one kind and counts the rest, so one kind cannot hide the others.
class Tally {
public:
  Tally(Findings& findings, std::string what) : findings_(findings), what_(std::move(what)) {}
  void at(const std::string& entry, const std::string& message) {
    if (++count_ <= kShown) findings_.at(entry, message);
  }
  void finish() {
    if (count_ > kShown) findings_.whole("and " + std::to_string(count_ - kShown) + " more " + what_);
  }

private:
  static constexpr std::size_t kShown = 8;
  Findings& findings_;
  std::string what_;
  std::size_t count_ = 0;
};

// The profiles whose limits bound what is read before the manifest names one: the caller's, or every
// bundled one.
std::vector<Profile> candidateProfiles(const InspectOptions& options) {
  if (options.profile) return {*options.profile};
  std::vector<Profile> out;
  for (const std::string& name : bundledProfileNames()) try {
      out.push_back(loadProfile(name));
    } catch (const ProfileError&) {
      // A broken bundled profile cannot vouch for any job; jobs naming it are refused later.
    }
  return out;
}

ProfileLimits widestLimits(const std::vector<Profile>& profiles) {
  ProfileLimits w{0, 0, 0, 4096, 1u << 20, 65536};
  for (const Profile& p : profiles) {
    const ProfileLimits l = limitsOf(p);
    w.maxEntries = std::max(w.maxEntries, l.maxEntries);
    w.maxManifestBytes = std::max(w.maxManifestBytes, l.maxManifestBytes);
    w.maxManifestValues = std::max(w.maxManifestValues, l.maxManifestValues);
  }
  return w;
}

class Inspector {
public:
  Inspector(const fs::path& job, const InspectOptions& options, InspectReport& report)
      : job_(job), options_(options), report_(report), findings_(job.string()) {}

  void run() {
    candidates_ = candidateProfiles(options_);
    limits_ = widestLimits(candidates_);
    try {
      reader_ = openJobReader(job_, limits_.maxEntries, kMaxFolderDepth);
    } catch (const JobReadError& e) {
      findings_.located(e.what());
      return finish();
    }
    indexEntries();
    if (readManifest() && resolveProfile() && readJobLayout()) {
      checkEntries();
      if (!gcvf()) checkBuildFile();
      checkPreviews();
      checkReport();
      checkLayers();
      if (gcvf()) checkGcvfConfig();  // its VoxelCounts are checked against the decoded images
    }
    finish();
  }

private:
  void finish() { report_.defects = findings_.take(); }
  bool gcvf() const { return profile_.jobFormat == JobFormat::Gcvf; }

  // Names every entry that no job may hold; keeps the safe, unique, regular files for reading.
  void indexEntries() {
    std::map<std::string, std::string> seen;  // lowercase name -> name as first found
    std::set<std::string> ambiguous;
    for (const JobEntry& e : reader_->entries()) {
      if (const auto why = unsafeEntryName(e.name)) {
        findings_.at(e.name, "unsafe entry name: it " + *why + "; a job's names are plain relative paths");
        reported_.insert(e.name);
        continue;
      }
      const auto [it, fresh] = seen.emplace(lowercase(e.name), e.name);
      if (!fresh) {
        findings_.at(e.name, it->second == e.name ? "appears more than once in the job"
                                                  : "differs from " + printableName(it->second) +
                                                        " only in letter case: Windows and macOS would keep one of them");
        ambiguous.insert(it->second);
        reported_.insert(e.name);
        continue;
      }
      if (e.kind == EntryKind::Other) {
        findings_.at(e.name, "is " + e.otherWhat + "; a job holds only regular files and folders (it was not opened)");
        reported_.insert(e.name);
      } else if (e.kind == EntryKind::Directory) {
        folders_.insert(e.name);
      } else {
        files_[e.name] = &e;
      }
    }
    for (const std::string& name : ambiguous) {
      files_.erase(name);
      reported_.insert(name);
    }
    if (reader_->truncated())
      findings_.whole("holds more than " + std::to_string(limits_.maxEntries) + " entries, more than any job can; the rest were not listed");
  }

  bool readManifest() {
    const auto it = files_.find(kManifestName);
    if (it == files_.end()) {
      if (!reported_.count(kManifestName)) findings_.whole(std::string("no ") + kManifestName + ": not a finished rodfab job");
      return false;
    }
    try {
      const Bytes text = reader_->read(*it->second, limits_.maxManifestBytes);
      report_.manifest = parseUntrustedJson(text, limits_.maxManifestValues);
      return true;
    } catch (const JobReadError& e) {
      findings_.located(e.what());
    } catch (const std::runtime_error& e) {
      findings_.at(kManifestName, std::string("cannot be read: ") + e.what());
    }
    report_.manifest = nullptr;
    return false;
  }

  // The profile comes from the caller or, by name only, from the bundled ones: never from a path.
  bool resolveProfile() {
    if (!findProfile()) return false;
    // A job made in another print mode than the profile's default (the J750's high-mix) says so.
    const json& m = report_.manifest;
    const json* mode = m["profile"].is_object() && m["profile"].contains("print_mode") ? &m["profile"]["print_mode"] : nullptr;
    if (!mode || (mode->is_string() && mode->get<std::string>() == profile_.printMode)) return true;
    try {
      if (!mode->is_string()) throw ProfileError(profile_.name, {{"", "expected the name of a print mode"}});
      profile_ = withPrintMode(profile_, mode->get<std::string>());
      return true;
    } catch (const ProfileError& e) {
      findings_.at(kManifestName, "profile.print_mode: " + printableName(e.issues().front().message));
      return false;
    }
  }

  bool findProfile() {
    if (options_.profile) {
      profile_ = *options_.profile;
      return true;
    }
    const json& m = report_.manifest;
    const json* name = m.is_object() && m.contains("profile") && m["profile"].is_object() && m["profile"].contains("name")
                           ? &m["profile"]["name"]
                           : nullptr;
    if (!name || !name->is_string()) {
      findings_.at(kManifestName, "profile.name: missing; expected the name of a bundled printer profile");
      return false;
    }
    for (const Profile& p : candidates_)
      if (p.name == name->get<std::string>()) {
        profile_ = p;
        return true;
      }
    std::string bundled;
    for (const Profile& p : candidates_) bundled += (bundled.empty() ? "" : ", ") + p.name;
    findings_.at(kManifestName, "profile.name: \"" + printableName(name->get<std::string>()) +
                                    "\" is not a bundled profile (bundled: " + (bundled.empty() ? "none" : bundled) +
                                    "); inspect --profile FILE checks a job made with another profile file");
    return false;
  }

  bool readJobLayout() {
    InspectSummary& s = report_.summary;
    s.profile = profile_.name;
    s.printer = profile_.printer;
    s.xDpi = profile_.xDpi;
    s.yDpi = profile_.yDpi;
    s.layerThicknessMm = profile_.layerThicknessMm();
    s.bitDepth = profile_.imageBitDepth();
    std::optional<JobLayout> layout = readLayout(report_.manifest, profile_, findings_, s);
    if (!layout) return false;
    layout_ = std::move(*layout);
    report_.width = layout_.width;
    report_.height = layout_.height;
    report_.layers = layout_.layers;
    return true;
  }

  void checkEntries() {
    std::set<std::string> parents;  // folders that hold expected entries
    for (const auto& [name, expected] : layout_.expected)
      for (std::size_t slash = name.find('/'); slash != std::string::npos; slash = name.find('/', slash + 1))
        parents.insert(name.substr(0, slash + 1));
    Tally unexpected(findings_, "unexpected entries");
    for (const std::string& folder : folders_)
      if (!parents.count(folder)) unexpected.at(folder, "unexpected folder: a job for " + profile_.name + " has none of that name");
    for (const auto& [name, entry] : files_)
      if (!layout_.expected.count(name))
        unexpected.at(name, "unexpected entry: not part of a " + std::to_string(layout_.layers) + "-layer " +
                                toString(layout_.imageFormat) + " job for " + profile_.name);
    unexpected.finish();
    reportMissing();
    Tally table(findings_, "problems in the manifest's file table");
    for (const auto& [name, expected] : layout_.expected)
      if (expected.role != EntryRole::Manifest && !layout_.listed.count(name))
        table.at(kManifestName, "files: lacks " + printableName(name) + ", which the job must hold");
    for (const auto& [name, listed] : layout_.listed)
      if (!layout_.expected.count(name)) table.at(kManifestName, "files: lists " + printableName(name) + ", which is not part of the job");
    table.finish();
  }

  // Missing entries; a material whose every image is missing is one finding, not one per layer.
  void reportMissing() {
    std::vector<int> missingImages(layout_.materials.size(), 0);
    for (const auto& [name, expected] : layout_.expected)
      if (expected.role == EntryRole::Layer && !files_.count(name)) ++missingImages[static_cast<std::size_t>(expected.material)];
    for (std::size_t n = 0; n < layout_.materials.size(); ++n)
      if (missingImages[n] == layout_.layers)
        findings_.whole("every " + layout_.materials[n]->name + " image is missing (" + std::to_string(layout_.layers) +
                        " layers): the job cannot print its " + toString(layout_.materials[n]->role) + " material");
    Tally missing(findings_, "missing entries");
    for (const auto& [name, expected] : layout_.expected) {
      if (files_.count(name) || reported_.count(name)) continue;
      if (expected.role == EntryRole::Layer && missingImages[static_cast<std::size_t>(expected.material)] == layout_.layers) continue;
      missing.at(name, "missing: a " + std::to_string(layout_.layers) + "-layer job for " + profile_.name + " holds it");
    }
    missing.finish();
  }

  // Streams an expected entry: its declared and actual size against its cap, its size and checksum
  // against the manifest. Keeps at most `keep` leading bytes. nullopt after a finding.
  std::optional<Bytes> fetch(const std::string& name, std::uint64_t keep, Findings& out) const {
    const auto file = files_.find(name);
    const auto listed = layout_.listed.find(name);
    if (file == files_.end() || listed == layout_.listed.end()) return std::nullopt;  // reported by checkEntries
    const std::uint64_t cap = layout_.expected.at(name).maxBytes;
    if (file->second->declaredBytes > cap) {
      out.at(name, "declares " + std::to_string(file->second->declaredBytes) + " bytes; at most " + std::to_string(cap) +
                       " fit a " + std::to_string(layout_.width) + " x " + std::to_string(layout_.height) + " job's entry (not read)");
      return std::nullopt;
    }
    Bytes kept;
    Sha256 sha;
    std::uint64_t bytes = 0;
    try {
      reader_->stream(*file->second, cap, [&](std::span<const std::uint8_t> chunk) {
        sha.update(chunk);
        bytes += chunk.size();
        const std::size_t room = static_cast<std::size_t>(std::min<std::uint64_t>(keep - kept.size(), chunk.size()));
        kept.insert(kept.end(), chunk.begin(), chunk.begin() + static_cast<std::ptrdiff_t>(room));
      });
    } catch (const JobReadError& e) {
      out.located(e.what());
      return std::nullopt;
    }
    if (bytes != listed->second.bytes || sha.hex() != listed->second.sha256) {
      out.at(name, "checksum mismatch (the file was changed or damaged): " + std::to_string(bytes) +
                       " bytes, the manifest says " + std::to_string(listed->second.bytes));
      return std::nullopt;
    }
    ++filesChecked_;
    return kept;
  }

  void checkBuildFile() {
    const std::string& name = profile_.buildFileName;
    const auto data = fetch(name, UINT64_MAX, findings_);
    if (!data) return;
    const auto values = buildFileValues(std::string(data->begin(), data->end()));
    const auto expect = [&](const std::string& key, const std::string& want) {
      const auto it = values.find(key);
      if (it == values.end() || it->second != want)
        findings_.at(name, "expected '" + key + " = " + want + ";'" +
                               (it == values.end() ? std::string(", found no such line") : ", found '" + printableName(it->second) + "'"));
    };
    expect("Format version", std::to_string(profile_.buildFormatVersion));
    expect("Number of slices", std::to_string(layout_.layers));
    std::ostringstream thickness;
    thickness << profile_.layerThicknessMm();  // as the writer prints it
    expect("Layer thickness", thickness.str());
    expect("Support", profile_.material(MaterialRole::Support).name);
    for (const ProfileMaterial* m : layout_.materials) expect(m->name, profile_.layerFilePattern(*m, layout_.imageFormat));
  }

  // Previews are only looked at by people: their checksum and that they are 8-bit RGB PNGs suffice.
  void checkPreviews() {
    for (const auto& [name, expected] : layout_.expected) {
      if (expected.role != EntryRole::Preview && expected.role != EntryRole::ContactSheet) continue;
      const auto head = fetch(name, 26, findings_);
      if (!head) continue;
      static constexpr std::uint8_t kSignature[16] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R'};
      if (head->size() < 26 || !std::equal(kSignature, kSignature + 16, head->begin()) || (*head)[24] != 8 || (*head)[25] != 2)
        findings_.at(name, "is not an 8-bit RGB PNG image");
    }
  }

  // The job report (report.html) is read by people too: its checksum, and that it is an HTML page.
  void checkReport() {
    const auto it = layout_.expected.find(kReportName);
    if (it == layout_.expected.end()) return;
    const auto head = fetch(kReportName, 15, findings_);
    static constexpr std::string_view kDoctype = "<!DOCTYPE html>";
    if (head && std::string_view(reinterpret_cast<const char*>(head->data()), head->size()) != kDoctype)
      findings_.at(kReportName, "is not an HTML page (expected it to start with <!DOCTYPE html>)");
  }

  void checkLayers() {
    const std::size_t materials = layout_.materials.size();
    const std::uint64_t imageBytes = (static_cast<std::uint64_t>(layout_.width) + 7) / 8 * static_cast<std::uint64_t>(layout_.height);
    const std::uint64_t fileCap = layout_.expected.at(profile_.layerFileName(*layout_.materials[0], 0, layout_.imageFormat)).maxBytes;
    const std::uint64_t perLayer = materials * (fileCap + imageBytes);
    const int workers = static_cast<int>(std::clamp<std::uint64_t>(kLayerMemoryBudget / std::max<std::uint64_t>(perLayer, 1), 1,
                                                                   static_cast<std::uint64_t>(tbb::this_task_arena::max_concurrency())));
    std::vector<LayerResult> results(static_cast<std::size_t>(layout_.layers), LayerResult(job_.string()));
    tbb::task_arena arena(workers);
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<int>(0, layout_.layers, 1), [&](const tbb::blocked_range<int>& range) {
        for (int l = range.begin(); l != range.end(); ++l) checkLayer(l, results[static_cast<std::size_t>(l)]);
      });
    });
    std::vector<DecodedMoments> moments(materials);
    std::vector<std::uint64_t> totals(materials, 0);
    for (const LayerResult& r : results) {
      findings_.merge(r.findings);
      for (std::size_t n = 0; n < materials; ++n) {
        totals[n] += r.voxels[n];
        moments[n].merge(r.moments[n]);
      }
    }
    const auto& v = profile_.voxelSizeMm;
    for (std::size_t n = 0; n < materials; ++n) {
      const ProfileMaterial& m = *layout_.materials[n];
      const double ml = static_cast<double>(totals[n]) * v[0] * v[1] * v[2] / 1000.0;
      report_.materials.push_back({m.name, m.role, totals[n], ml, ml * m.densityGPerMl});
    }
    checkOrientation(moments);
    report_.filesChecked = filesChecked_;
  }

  // One layer image decoded and checked against the job's size and resolution; nullopt after a finding.
  std::optional<Bitmap> layerImage(int l, std::size_t n, Findings& out) const {
    const std::string name = profile_.layerFileName(*layout_.materials[n], l, layout_.imageFormat);
    const auto data = fetch(name, UINT64_MAX, out);
    if (!data) return std::nullopt;
    DecodedBitmap decoded;
    try {
      decoded = layout_.imageFormat == ImageFormat::Png ? decodePng1(*data) : decodeBmp(*data);
    } catch (const ImageError& e) {
      out.at(name, e.what());
      return std::nullopt;
    }
    if (decoded.bitmap.width() != layout_.width || decoded.bitmap.height() != layout_.height) {
      out.at(name, std::to_string(decoded.bitmap.width()) + " x " + std::to_string(decoded.bitmap.height()) +
                       " pixels; the job's images are " + std::to_string(layout_.width) + " x " + std::to_string(layout_.height));
      return std::nullopt;
    }
    const std::uint32_t xPpm = pixelsPerMetre(profile_.xDpi), yPpm = pixelsPerMetre(profile_.yDpi);
    if (decoded.xPixelsPerMetre != xPpm || decoded.yPixelsPerMetre != yPpm) {
      const std::string why = decoded.xPixelsPerMetre == yPpm && decoded.yPixelsPerMetre == xPpm
                                  ? " (x and y swapped: the part would print at twice or half its size)"
                                  : "";
      out.at(name, "resolution " + std::to_string(decoded.xPixelsPerMetre) + " x " + std::to_string(decoded.yPixelsPerMetre) +
                       " pixels/m; expected " + std::to_string(xPpm) + " x " + std::to_string(yPpm) + " (" +
                       std::to_string(profile_.xDpi) + " x " + std::to_string(profile_.yDpi) + " dpi)" + why);
    }
    return std::move(decoded.bitmap);
  }

  void checkLayer(int l, LayerResult& out) const {
    if (gcvf()) return checkGcvfLayer(l, out);
    const std::size_t materials = layout_.materials.size();
    out.voxels.assign(materials, 0);
    out.moments.assign(materials, {});
    std::vector<std::optional<Bitmap>> bitmaps(materials);
    for (std::size_t n = 0; n < materials; ++n) {
      bitmaps[n] = layerImage(l, n, out.findings);
      if (!bitmaps[n]) continue;
      countVoxels(*bitmaps[n], l, out.moments[n]);
      out.voxels[n] = out.moments[n].count;
      const auto& listed = layout_.layerVoxels[static_cast<std::size_t>(l)][n];
      if (listed && *listed != out.voxels[n])
        out.findings.at(profile_.layerFileName(*layout_.materials[n], l, layout_.imageFormat),
                        "has " + std::to_string(out.voxels[n]) + " voxels; the manifest says " + std::to_string(*listed) +
                            " (layers[" + std::to_string(l) + "].voxels." + layout_.materials[n]->name + ")");
    }
    // No voxel may hold two materials: neither two model materials nor support inside the model.
    for (std::size_t a = 0; a < materials; ++a)
      for (std::size_t b = a + 1; b < materials; ++b) {
        if (!bitmaps[a] || !bitmaps[b]) continue;
        if (const std::uint64_t both = countCommonBits(bitmaps[a]->bytes(), bitmaps[b]->bytes()))
          out.findings.at(profile_.layerFileName(*layout_.materials[a], l, layout_.imageFormat),
                          std::to_string(both) + " voxels hold both " + layout_.materials[a]->name + " and " + layout_.materials[b]->name);
      }
  }

  // A GrabCAD Voxel Print layer: one RGBA image, each colour a material (nothing else), counts as listed.
  void checkGcvfLayer(int l, LayerResult& out) const {
    const std::size_t materials = layout_.materials.size();
    out.voxels.assign(materials, 0);
    out.moments.assign(materials, {});
    const std::string name = profile_.layerFileName(*layout_.materials[0], l, layout_.imageFormat);
    const auto data = fetch(name, UINT64_MAX, out.findings);
    if (!data) return;
    GcvfLayerImage image;
    try {
      image = decodeGcvfLayer(*data, profile_, layout_.materials, layout_.width, layout_.height);
    } catch (const ImageError& e) {
      return out.findings.at(name, e.what());
    }
    ++gcvfLayersDecoded_;
    if (image.xPixelsPerMetre != pixelsPerMetre(profile_.xDpi) || image.yPixelsPerMetre != pixelsPerMetre(profile_.yDpi))
      out.findings.at(name, "resolution " + std::to_string(image.xPixelsPerMetre) + " x " + std::to_string(image.yPixelsPerMetre) +
                                " pixels/m; expected " + std::to_string(profile_.xDpi) + " x " + std::to_string(profile_.yDpi) + " dpi");
    if (image.foreignPixels)
      out.findings.at(name, std::to_string(image.foreignPixels) + " pixels have a colour that is not in the material list (first: " +
                                gcvfRgbaText(image.firstForeign) + " at column " + std::to_string(image.firstForeignColumn) +
                                ", row " + std::to_string(image.firstForeignRow) + ")");
    for (std::size_t n = 0; n < materials; ++n) {
      countVoxels(image.bitmaps[n], l, out.moments[n]);
      out.voxels[n] = out.moments[n].count;
      const auto& listed = layout_.layerVoxels[static_cast<std::size_t>(l)][n];
      if (listed && *listed != out.voxels[n])
        out.findings.at(name, "has " + std::to_string(out.voxels[n]) + " " + layout_.materials[n]->name + " voxels; the manifest says " +
                                  std::to_string(*listed) + " (layers[" + std::to_string(l) + "].voxels." + layout_.materials[n]->name + ")");
    }
  }

  void checkGcvfConfig() {
    const std::string& name = profile_.buildFileName;
    const auto data = fetch(name, UINT64_MAX, findings_);
    if (!data) return;
    // VoxelCount is checked against the images only when every one was read (else the layers are the defect).
    const bool counted = gcvfLayersDecoded_ == layout_.layers;
    for (const std::string& problem : printer_profiles::checkGcvfConfig(*data, profile_, layout_.width, layout_.height, layout_.layers,
                                                                        report_.materials, counted))
      findings_.at(name, problem);
  }

  // Word by word, skipping empty words (layers are mostly empty), one moments entry per row: the sums
  // are of integers, exact in any order.
  void countVoxels(const Bitmap& b, int l, DecodedMoments& moments) const {
    const std::size_t stride = b.stride();
    for (int r = 0; r < b.height(); ++r) {
      const std::uint8_t* row = b.row(r);
      std::int64_t count = 0, sumI = 0;
      int iMin = INT32_MAX, iMax = INT32_MIN;
      for (std::size_t at = 0; at < stride; at += 8) {
        std::uint64_t word = 0;
        const std::size_t end = std::min(stride, at + 8);
        std::memcpy(&word, row + at, end - at);
        if (!word) continue;
        for (std::size_t byte = at; byte < end; ++byte) {
          const std::uint8_t bits = row[byte];
          if (!bits) continue;
          const int i0 = layout_.firstColumnI + static_cast<int>(byte) * 8;
          const int n = kBitCounts[bits];
          count += n;
          sumI += static_cast<std::int64_t>(n) * i0 + kBitPositionSums[bits];
          iMin = std::min(iMin, i0 + std::countl_zero(bits));
          iMax = std::max(iMax, i0 + 7 - std::countr_zero(bits));
        }
      }
      if (count) moments.add(layout_.topRowJ - r, layout_.firstLayerK + l, static_cast<int>(count), static_cast<double>(sumI), iMin, iMax);
    }
  }

  // The images mapped back through the frame must land where the manifest says the part is (computed
  // from the grid by the writer): otherwise they are mirrored, flipped or shifted.
  void checkOrientation(const std::vector<DecodedMoments>& moments) {
    const auto& v = profile_.voxelSizeMm;
    const auto& o = layout_.originMm;
    const auto toMm = [&](const std::array<double, 3>& ijk) {
      return std::array<double, 3>{o[0] + ijk[0] * v[0], o[1] + ijk[1] * v[1], o[2] + ijk[2] * v[2]};
    };
    for (std::size_t n = 0; n < layout_.materials.size(); ++n) {
      const auto& record = layout_.orientation[n];
      const DecodedMoments& mo = moments[n];
      if (!record || record->voxels != mo.count || !mo.count) continue;  // counts are reported layer by layer
      const double c = static_cast<double>(mo.count);
      const std::array<double, 3> got[3] = {toMm({1.0 * mo.min[0], 1.0 * mo.min[1], 1.0 * mo.min[2]}),
                                            toMm({1.0 * mo.max[0], 1.0 * mo.max[1], 1.0 * mo.max[2]}),
                                            toMm({mo.sum[0] / c, mo.sum[1] / c, mo.sum[2] / c})};
      const std::array<double, 3> want[3] = {record->minMm, record->maxMm, record->centroidMm};
      const char* what[3] = {"min", "max", "centroid"};
      for (int q = 0; q < 3; ++q) {
        bool same = true;
        for (int a = 0; a < 3; ++a) same = same && std::abs(want[q][a] - got[q][a]) <= 1e-6 * std::max(1.0, std::abs(want[q][a]));
        if (same) continue;
        findings_.whole(layout_.materials[n]->name + ": the images put the " + what[q] + " of the part at " + fmt3(got[q]) +
                        " mm, the manifest at " + fmt3(want[q]) + " mm: the images are mirrored, flipped or shifted against the design");
        break;
      }
    }
  }

  fs::path job_;
  const InspectOptions& options_;
  InspectReport& report_;
  Findings findings_;
  std::vector<Profile> candidates_;
  ProfileLimits limits_;
  std::unique_ptr<JobReader> reader_;
  std::map<std::string, const JobEntry*> files_;  // safe, unambiguous regular files by name
  std::set<std::string> folders_;                 // safe folder entries ("previews/")
  std::set<std::string> reported_;                // names already found wanting
  Profile profile_;
  JobLayout layout_;
  mutable std::atomic<std::size_t> filesChecked_{0};
  mutable std::atomic<int> gcvfLayersDecoded_{0};  // gcvf layer images read without a defect of their own
};

}  // namespace

InspectReport inspectJobFiles(const JobFiles& files, const InspectOptions& options) {
  InspectReport report;
  report.job = files.path();
  Inspector(files.path(), options, report).run();
  return report;
}

InspectReport inspectJob(const fs::path& job, const InspectOptions& options) {
  InspectReport report;
  report.job = job;
  if (job.filename().string().find(".rodfab-partial-") != std::string::npos) {
    report.defects.push_back(job.string() + ": an unfinished job (temporary name of an interrupted or running write)");
    return report;
  }
  Inspector(job, options, report).run();
  return report;
}

}  // namespace rodfab::printer_profiles
