#include "printer_profiles/inspect.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <map>
#include <regex>
#include <set>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr std::size_t kMaxDefects = 60;

struct ManifestMaterial {
  std::string name;
  MaterialRole role = MaterialRole::Rigid;
  double density = 0.0;
};

// Voxel index sums of one material as decoded from the images, to compare with the manifest's.
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
  std::vector<std::string> defects;
  std::vector<std::uint64_t> voxels;           // per manifest material
  std::vector<DecodedMoments> moments;         // per manifest material
};

std::string fmt3(const std::array<double, 3>& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.4f, %.4f, %.4f)", v[0], v[1], v[2]);
  return buf;
}

// A manifest field that is missing or of the wrong type.
class ManifestError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

class Inspector {
public:
  Inspector(const JobFiles& files, InspectReport& report) : files_(files), report_(report) {}

  void run() {
    if (!files_.contains(kManifestName)) {
      defect(std::string("no ") + kManifestName + ": not a finished rodfab job");
      return;
    }
    try {
      const Bytes text = files_.read(kManifestName);
      report_.manifest = json::parse(text.begin(), text.end());
    } catch (const std::exception& e) {
      defect(std::string(kManifestName) + ": cannot be read as JSON (" + e.what() + ")");
      return;
    }
    try {
      readManifest();
    } catch (const std::exception& e) {  // ManifestError or json::exception
      defect(std::string(kManifestName) + ": " + e.what());
      return;
    }
    if (!report_.ok()) return;
    try {
      checkOtherFiles();
      checkBuildFile();
      checkLayers();
    } catch (const std::exception& e) {  // a manifest entry of the wrong shape, an unreadable file
      defect(std::string("cannot finish the inspection: ") + e.what());
    }
  }

private:
  void defect(const std::string& message) {
    if (report_.defects.size() < kMaxDefects) report_.defects.push_back(message);
    else if (report_.defects.size() == kMaxDefects) report_.defects.push_back("... and more defects");
  }

  // Reads a manifest field, naming it when it is missing or of the wrong type.
  template <typename T>
  T field(const json& parent, const std::string& path, const std::string& key) {
    const auto it = parent.find(key);
    if (it == parent.end()) throw ManifestError("missing field " + path + key);
    try {
      return it->get<T>();
    } catch (const json::exception&) {
      throw ManifestError("field " + path + key + " has the wrong type: " + it->dump());
    }
  }

  void readManifest() {
    const json& m = report_.manifest;
    if (field<std::string>(m, "", "format") != kJobFormat) defect(std::string("manifest format is not ") + kJobFormat);
    const json& profile = m.at("profile");
    profileName_ = field<std::string>(profile, "profile.", "name");
    xDpi_ = field<int>(profile, "profile.", "x_dpi");
    yDpi_ = field<int>(profile, "profile.", "y_dpi");
    voxel_ = field<std::array<double, 3>>(profile, "profile.", "voxel_size_mm");
    alignment_ = field<int>(profile, "profile.", "column_alignment");
    const json& image = m.at("image");
    imageFormat_ = field<std::string>(image, "image.", "format");
    width_ = field<int>(image, "image.", "width");
    height_ = field<int>(image, "image.", "height");
    layers_ = field<int>(m, "", "layer_count");
    report_.width = width_;
    report_.height = height_;
    report_.layers = layers_;
    const json& frame = m.at("frame");
    origin_ = field<std::array<double, 3>>(frame, "frame.", "origin_mm");
    firstColumnI_ = field<int>(frame, "frame.", "first_column_i");
    topRowJ_ = field<int>(frame, "frame.", "top_row_j");
    firstLayerK_ = field<int>(frame, "frame.", "first_layer_k");
    buildFile_ = field<std::string>(m, "", "build_file");
    for (const json& jm : m.at("materials")) {
      ManifestMaterial mm;
      mm.name = field<std::string>(jm, "materials[].", "name");
      const std::string role = field<std::string>(jm, "materials[].", "role");
      mm.role = role == "rigid" ? MaterialRole::Rigid : role == "rubbery" ? MaterialRole::Rubbery : MaterialRole::Support;
      mm.density = field<double>(jm, "materials[].", "density_g_per_ml");
      materials_.push_back(mm);
    }
    for (const auto& [name, entry] : m.at("files").items())
      fileTable_[name] = {field<std::uint64_t>(entry, "files." + name + ".", "bytes"), field<std::string>(entry, "files." + name + ".", "sha256")};

    // The resolution must tell one story: dpi, voxel size, and the bundled profile of that name.
    const int dpi[2] = {xDpi_, yDpi_};
    const char* axis[2] = {"x", "y"};
    for (int a = 0; a < 2; ++a)
      if (dpi[a] <= 0 || std::abs(25.4 / dpi[a] - voxel_[a]) > 0.005 * voxel_[a])
        defect("manifest: " + std::string(axis[a]) + "_dpi = " + std::to_string(dpi[a]) + " does not match the voxel size " +
               std::to_string(voxel_[a]) + " mm along " + axis[a] + " (600/300 dpi swapped?)");
    try {
      const Profile bundled = loadProfile(profileName_);
      if (bundled.xDpi != xDpi_ || bundled.yDpi != yDpi_)
        defect("manifest: " + std::to_string(xDpi_) + " x " + std::to_string(yDpi_) + " dpi, but the " + profileName_ +
               " profile is " + std::to_string(bundled.xDpi) + " x " + std::to_string(bundled.yDpi) +
               " dpi (x is the image columns): the part would print at the wrong size");
    } catch (const ProfileError&) {
      // Not a bundled profile: the manifest's own values were checked above.
    }
    if (width_ <= 0 || height_ <= 0 || layers_ <= 0) defect("manifest: image size or layer count is not positive");
    if (alignment_ <= 0 || width_ % alignment_ != 0)
      defect("manifest: image width " + std::to_string(width_) + " is not a multiple of " + std::to_string(alignment_));
    if (imageFormat_ != "bmp" && imageFormat_ != "png") defect("manifest: image format '" + imageFormat_ + "' is not bmp or png");
    const json& layerList = m.at("layers");
    if (!layerList.is_array() || static_cast<int>(layerList.size()) != layers_)
      defect("manifest: layers lists " + std::to_string(layerList.size()) + " layers; layer_count is " + std::to_string(layers_));
  }

  // Checksums of every file; files the manifest does not list are defects too.
  bool checkFile(const std::string& name, const Bytes& data) {
    const auto it = fileTable_.find(name);
    if (it == fileTable_.end()) {
      defect(name + ": not listed in the manifest");
      return false;
    }
    if (data.size() != it->second.first || sha256Hex(data) != it->second.second) {
      defect(name + ": checksum mismatch (the file was changed or damaged)");
      return false;
    }
    return true;
  }

  void checkOtherFiles() {
    std::set<std::string> layerFiles;
    for (const json& l : report_.manifest.at("layers"))  // malformed entries are reported by checkLayers
      if (l.is_object() && l.contains("files") && l["files"].is_object())
        for (const auto& [material, file] : l["files"].items())
          if (file.is_string()) layerFiles.insert(file.get<std::string>());
    for (const auto& [name, entry] : fileTable_) {
      (void)entry;
      if (!files_.contains(name)) defect(name + ": listed in the manifest but missing from the job");
    }
    for (const std::string& name : files_.names()) {
      if (name == kManifestName || layerFiles.count(name)) continue;
      if (!fileTable_.count(name)) {
        defect(name + ": not listed in the manifest");
        continue;
      }
      try {
        checkFile(name, files_.read(name));
        ++report_.filesChecked;
      } catch (const std::exception& e) {
        defect(e.what());
      }
    }
  }

  void checkBuildFile() {
    if (!files_.contains(buildFile_)) return;  // reported as missing above
    const Bytes data = files_.read(buildFile_);
    const std::string text(data.begin(), data.end());
    std::smatch match;
    if (!std::regex_search(text, match, std::regex(R"(Number of slices\s*=\s*(\d+)\s*;)")) || std::stoi(match[1]) != layers_)
      defect(buildFile_ + ": 'Number of slices' does not say " + std::to_string(layers_));
    if (!std::regex_search(text, match, std::regex(R"(Layer thickness\s*=\s*([0-9.]+)\s*;)")) ||
        std::abs(std::stod(match[1]) - voxel_[2]) > 1e-9)
      defect(buildFile_ + ": 'Layer thickness' does not say " + std::to_string(voxel_[2]));
    for (const ManifestMaterial& mm : materials_)
      if (text.find(mm.name + " = ") == std::string::npos) defect(buildFile_ + ": no entry for " + mm.name);
  }

  void checkLayers() {
    const json& layerList = report_.manifest.at("layers");
    std::vector<LayerResult> results(static_cast<std::size_t>(layers_));
    const std::uint32_t xPpm = pixelsPerMetre(xDpi_), yPpm = pixelsPerMetre(yDpi_);
    tbb::parallel_for(tbb::blocked_range<int>(0, layers_, 1), [&](const tbb::blocked_range<int>& range) {
      for (int l = range.begin(); l != range.end(); ++l) {
        LayerResult& result = results[static_cast<std::size_t>(l)];
        try {
          checkLayer(l, layerList.at(static_cast<std::size_t>(l)), xPpm, yPpm, result);
        } catch (const std::exception& e) {
          result.defects.push_back("layer " + std::to_string(l) + ": manifest entry unreadable (" + e.what() + ")");
        }
      }
    });
    std::vector<DecodedMoments> moments(materials_.size());
    std::vector<std::uint64_t> totals(materials_.size(), 0);
    for (const LayerResult& r : results) {
      for (const std::string& d : r.defects) defect(d);
      for (std::size_t n = 0; n < materials_.size() && n < r.voxels.size(); ++n) {
        totals[n] += r.voxels[n];
        moments[n].merge(r.moments[n]);
      }
    }
    report_.filesChecked += static_cast<std::size_t>(layers_) * materials_.size();
    for (std::size_t n = 0; n < materials_.size(); ++n) {
      const double ml = static_cast<double>(totals[n]) * voxel_[0] * voxel_[1] * voxel_[2] / 1000.0;
      report_.materials.push_back({materials_[n].name, materials_[n].role, totals[n], ml, ml * materials_[n].density});
    }
    checkOrientation(moments);
  }

  void checkLayer(int l, const json& entry, std::uint32_t xPpm, std::uint32_t yPpm, LayerResult& out) const {
    out.voxels.assign(materials_.size(), 0);
    out.moments.assign(materials_.size(), {});
    const std::string where = "layer " + std::to_string(l);
    std::vector<Bitmap> bitmaps(materials_.size());
    std::vector<bool> have(materials_.size(), false);
    for (std::size_t n = 0; n < materials_.size(); ++n) {
      const ManifestMaterial& mm = materials_[n];
      const auto fileIt = entry.at("files").find(mm.name);
      if (fileIt == entry.at("files").end()) {
        out.defects.push_back(where + ": no " + mm.name + " file in the manifest");
        continue;
      }
      const std::string name = fileIt->get<std::string>();
      Bytes data;
      try {
        data = files_.read(name);
      } catch (const std::exception& e) {
        out.defects.push_back(e.what());
        continue;
      }
      const auto listed = fileTable_.find(name);
      if (listed == fileTable_.end()) {
        out.defects.push_back(name + ": not listed in the manifest's files");
        continue;
      }
      if (data.size() != listed->second.first || sha256Hex(data) != listed->second.second) {
        out.defects.push_back(name + ": checksum mismatch (the file was changed or damaged)");
        continue;
      }
      DecodedBitmap decoded;
      try {
        decoded = name.ends_with(".png") ? decodePng1(data) : decodeBmp(data);
      } catch (const ImageError& e) {
        out.defects.push_back(name + ": " + e.what());
        continue;
      }
      if (decoded.bitmap.width() != width_ || decoded.bitmap.height() != height_) {
        out.defects.push_back(name + ": " + std::to_string(decoded.bitmap.width()) + " x " + std::to_string(decoded.bitmap.height()) +
                              " pixels; the job's images are " + std::to_string(width_) + " x " + std::to_string(height_));
        continue;
      }
      if (decoded.xPixelsPerMetre != xPpm || decoded.yPixelsPerMetre != yPpm) {
        std::string why = decoded.xPixelsPerMetre == yPpm && decoded.yPixelsPerMetre == xPpm
                              ? " (x and y swapped: the part would print at twice or half its size)"
                              : "";
        out.defects.push_back(name + ": resolution " + std::to_string(decoded.xPixelsPerMetre) + " x " +
                              std::to_string(decoded.yPixelsPerMetre) + " pixels/m; expected " + std::to_string(xPpm) + " x " +
                              std::to_string(yPpm) + " (" + std::to_string(xDpi_) + " x " + std::to_string(yDpi_) + " dpi)" + why);
      }
      bitmaps[n] = std::move(decoded.bitmap);
      have[n] = true;
    }
    const auto counts = entry.at("voxels");
    for (std::size_t n = 0; n < materials_.size(); ++n) {
      if (!have[n]) continue;
      const Bitmap& b = bitmaps[n];
      for (int r = 0; r < height_; ++r) {
        const std::uint8_t* row = b.row(r);
        for (std::size_t byte = 0; byte < b.stride(); ++byte) {
          const std::uint8_t bits = row[byte];
          if (!bits) continue;
          const int i0 = firstColumnI_ + static_cast<int>(byte) * 8;
          int n8 = 0;
          double sumI = 0;
          for (int x = 0; x < 8; ++x)
            if ((bits >> (7 - x)) & 1) {
              ++n8;
              sumI += i0 + x;
            }
          out.moments[n].add(topRowJ_ - r, firstLayerK_ + l, n8, sumI, i0 + std::countl_zero(bits), i0 + 7 - std::countr_zero(bits));
        }
      }
      out.voxels[n] = out.moments[n].count;
      const std::uint64_t listed = counts.value(materials_[n].name, std::uint64_t{0});
      if (listed != out.voxels[n])
        out.defects.push_back(where + ": " + materials_[n].name + " has " + std::to_string(out.voxels[n]) +
                              " voxels; the manifest says " + std::to_string(listed));
    }
    // No voxel may hold two materials: neither two model materials nor support inside the model.
    for (std::size_t a = 0; a < materials_.size(); ++a)
      for (std::size_t b = a + 1; b < materials_.size(); ++b) {
        if (!have[a] || !have[b] || bitmaps[a].bytes().size() != bitmaps[b].bytes().size()) continue;  // sizes: reported above
        const std::uint64_t both = countCommonBits(bitmaps[a].bytes(), bitmaps[b].bytes());
        if (both)
          out.defects.push_back(where + ": " + std::to_string(both) + " voxels hold both " + materials_[a].name + " and " +
                                materials_[b].name);
      }
  }

  void checkOrientation(const std::vector<DecodedMoments>& moments) {
    const json& check = report_.manifest.value("orientation_check", json::object());
    const auto toMm = [&](const std::array<double, 3>& ijk) {
      return std::array<double, 3>{origin_[0] + ijk[0] * voxel_[0], origin_[1] + ijk[1] * voxel_[1], origin_[2] + ijk[2] * voxel_[2]};
    };
    for (std::size_t n = 0; n < materials_.size(); ++n) {
      const auto it = check.find(materials_[n].name);
      if (it == check.end()) continue;  // support has no orientation record
      const DecodedMoments& mo = moments[n];
      if (it->value("voxels", std::uint64_t{0}) != mo.count) continue;  // already reported layer by layer
      if (!mo.count) continue;
      const double c = static_cast<double>(mo.count);
      const std::array<double, 3> got[3] = {
          toMm({static_cast<double>(mo.min[0]), static_cast<double>(mo.min[1]), static_cast<double>(mo.min[2])}),
          toMm({static_cast<double>(mo.max[0]), static_cast<double>(mo.max[1]), static_cast<double>(mo.max[2])}),
          toMm({mo.sum[0] / c, mo.sum[1] / c, mo.sum[2] / c})};
      const char* keys[3] = {"min_mm", "max_mm", "centroid_mm"};
      for (int q = 0; q < 3; ++q) {
        const auto want = it->at(keys[q]).get<std::array<double, 3>>();
        for (int a = 0; a < 3; ++a)
          if (std::abs(want[a] - got[q][a]) > 1e-6 * std::max(1.0, std::abs(want[a]))) {
            defect(materials_[n].name + ": the images put the " + std::string(keys[q]).substr(0, std::string(keys[q]).size() - 3) +
                   " of the part at " + fmt3(got[q]) + " mm, the manifest at " + fmt3(want) +
                   " mm: the images are mirrored, flipped or shifted against the design");
            a = 3;
            q = 3;
          }
      }
    }
  }

  const JobFiles& files_;
  InspectReport& report_;
  std::string profileName_, imageFormat_, buildFile_;
  int xDpi_ = 0, yDpi_ = 0, alignment_ = 0, width_ = 0, height_ = 0, layers_ = 0;
  int firstColumnI_ = 0, topRowJ_ = 0, firstLayerK_ = 0;
  std::array<double, 3> voxel_{}, origin_{};
  std::vector<ManifestMaterial> materials_;
  std::map<std::string, std::pair<std::uint64_t, std::string>> fileTable_;
};

}  // namespace

InspectReport inspectJobFiles(const JobFiles& files) {
  InspectReport report;
  report.job = files.path();
  Inspector(files, report).run();
  return report;
}

InspectReport inspectJob(const fs::path& job) {
  InspectReport report;
  report.job = job;
  if (job.filename().string().find(".rodfab-partial-") != std::string::npos) {
    report.defects.push_back(job.string() + ": an unfinished job (temporary name of an interrupted or running write)");
    return report;
  }
  std::unique_ptr<JobFiles> files;
  try {
    files = openJobFiles(job);
  } catch (const std::exception& e) {
    report.defects.push_back(e.what());
    return report;
  }
  return inspectJobFiles(*files);
}

}  // namespace rodfab::printer_profiles
