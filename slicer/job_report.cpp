#include "slicer/job_report.hpp"

#include "common/markup.hpp"
#include "common/plot_canvas.hpp"

#include "calibration/plot.hpp"
#include "printer_profiles/job_writer.hpp"  // kVerifyDecodeEvery

#include <cairo.h>
#include <openssl/evp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>
#include <stdexcept>

namespace rodfab::slicer {

using nlohmann::json;
using printer_profiles::Bytes;

// ------------------------------------------------------------------------------------------ ClampMap

void ClampMap::View::resize(int w, int h) {
  width = w;
  height = h;
  const auto n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  model.assign(n, 0);
  below.assign(n, 0);
  above.assign(n, 0);
}

void ClampMap::View::count(int u, int v, std::uint64_t n, int clamp) {
  const std::size_t at = static_cast<std::size_t>(v) * static_cast<std::size_t>(width) + static_cast<std::size_t>(u);
  model[at] = 1;
  if (clamp == 1) below[at] += n;
  if (clamp == 2) above[at] += n;
}

ClampMap::ClampMap(const openvdb::CoordBBox& part, const std::array<double, 3>& voxelSizeMm, double floorMpa, double maxMpa)
    : part_(part), voxelMm_(voxelSizeMm), floor_(floorMpa), max_(maxMpa) {
  if (part.empty()) throw std::invalid_argument("ClampMap: the part box is empty");
  const openvdb::Coord d = part.dim();
  const int longest = std::max({d.x(), d.y(), d.z()});
  bin_ = std::max(1, (longest + kMaxBins - 1) / kMaxBins);
  const auto bins = [&](int voxels) { return (voxels + bin_ - 1) / bin_; };
  top_.resize(bins(d.x()), bins(d.y()));
  front_.resize(bins(d.x()), bins(d.z()));
}

bool ClampMap::clip(openvdb::CoordBBox& box) const {
  box = openvdb::CoordBBox(openvdb::Coord::maxComponent(box.min(), part_.min()) - part_.min(),
                           openvdb::Coord::minComponent(box.max(), part_.max()) - part_.min());
  return box.min().x() <= box.max().x() && box.min().y() <= box.max().y() && box.min().z() <= box.max().z();
}

// Every voxel of `box` holds `value`: one voxel, or an active tile.
void ClampMap::addBox(const openvdb::CoordBBox& box, float value) {
  const int clamp = !(value >= floor_) ? 1 : value > max_ ? 2 : 0;
  openvdb::CoordBBox clipped = box;
  if (!clip(clipped)) return;
  const openvdb::Coord lo = clipped.min(), hi = clipped.max();
  const auto extent = [](int a, int b) { return static_cast<std::uint64_t>(b - a + 1); };
  if (clamp == 1) below_ += extent(lo.x(), hi.x()) * extent(lo.y(), hi.y()) * extent(lo.z(), hi.z());
  if (clamp == 2) above_ += extent(lo.x(), hi.x()) * extent(lo.y(), hi.y()) * extent(lo.z(), hi.z());
  for (int i = lo.x(); i <= hi.x(); ++i) {
    for (int j = lo.y(); j <= hi.y(); ++j) top_.count(i / bin_, j / bin_, extent(lo.z(), hi.z()), clamp);
    for (int k = lo.z(); k <= hi.z(); ++k) front_.count(i / bin_, k / bin_, extent(lo.y(), hi.y()), clamp);
  }
}

void ClampMap::add(const openvdb::FloatGrid& modulus, int k0, int k1) {
  addOutline(modulus);  // the part as in bands without clamps, so the picture does not depend on the bands
  for (auto it = modulus.cbeginValueOn(); it; ++it) {
    openvdb::CoordBBox box;
    it.getBoundingBox(box);
    box.min().z() = std::max(box.min().z(), k0);
    box.max().z() = std::min(box.max().z(), k1 - 1);
    if (box.min().z() <= box.max().z()) addBox(box, *it);
  }
}

void ClampMap::addOutline(const openvdb::FloatGrid& modulus) {
  // Each leaf's origin from its parent's child mask, without reading the leaf: a leaf iterator and a
  // read of every leaf (a cache miss each) cost this pass 2 % of the lattice's slice, in the dither stage.
  using LeafParent = openvdb::FloatTree::RootNodeType::ChildNodeType::ChildNodeType;
  std::vector<const LeafParent*> parents;
  modulus.tree().getNodes(parents);
  for (const LeafParent* parent : parents) {
    for (auto child = parent->cbeginChildOn(); child; ++child) {
      openvdb::CoordBBox box = openvdb::CoordBBox::createCube(child.getCoord(), openvdb::FloatTree::LeafNodeType::DIM);
      if (clip(box)) outline(box);
    }
  }
  // Active tiles, whole (above the leaves: the iterator does not descend into them).
  auto tile = modulus.tree().cbeginValueOn();
  tile.setMaxDepth(openvdb::FloatTree::ValueOnCIter::LEAF_DEPTH - 1);
  for (; tile; ++tile) {
    openvdb::CoordBBox box;
    tile.getBoundingBox(box);
    if (clip(box)) outline(box);
  }
}

// Marks the bins `box` (clipped, relative to the part's corner) reaches in both views.
void ClampMap::outline(const openvdb::CoordBBox& box) {
  // Bin by bin rather than voxel by voxel: the outline only marks the bins the leaf reaches.
  const openvdb::Coord lo(box.min().x() / bin_, box.min().y() / bin_, box.min().z() / bin_);
  const openvdb::Coord hi(box.max().x() / bin_, box.max().y() / bin_, box.max().z() / bin_);
  for (int u = lo.x(); u <= hi.x(); ++u) {
    for (int v = lo.y(); v <= hi.y(); ++v) top_.count(u, v, 0, 0);
    for (int w = lo.z(); w <= hi.z(); ++w) front_.count(u, w, 0, 0);
  }
}

namespace {

struct Rgb {
  double r, g, b;
};

void setColor(cairo_t* cr, Rgb c) { cairo_set_source_rgb(cr, c.r, c.g, c.b); }

void label(cairo_t* cr, double x, double y, const std::string& text, double size = 13) {
  cairo_set_font_size(cr, size);
  cairo_move_to(cr, x, y);
  cairo_show_text(cr, text.c_str());
}

}  // namespace

Bytes ClampMap::renderPng() const {
  constexpr double kPanel = 380.0, kMargin = 40.0, kGap = 50.0;
  const openvdb::Coord d = part_.dim();
  const double xMm = d.x() * voxelMm_[0], yMm = d.y() * voxelMm_[1], zMm = d.z() * voxelMm_[2];
  const double scale = kPanel / std::max({xMm, yMm, zMm});  // pixels per mm, the same in both views
  const int width = static_cast<int>(2 * kMargin + kGap + 2 * xMm * scale) + 1;
  const int height = static_cast<int>(2 * kMargin + 30 + std::max(yMm, zMm) * scale) + 1;
  const common::PlotCanvas canvas(width, height);  // white, sans-serif
  cairo_t* cr = canvas.context();

  // A view's bins, v growing upwards (y or z), drawn with its lower-left corner at (x0, y0).
  const auto drawView = [&](const View& view, double x0, double y0, double vMm, const std::string& title) {
    const double bu = bin_ * voxelMm_[0] * scale, bv = bin_ * vMm * scale;
    for (int v = 0; v < view.height; ++v)
      for (int u = 0; u < view.width; ++u) {
        const std::size_t at = static_cast<std::size_t>(v) * static_cast<std::size_t>(view.width) + static_cast<std::size_t>(u);
        if (!view.model[at]) continue;
        const bool lo = view.below[at] > 0, hi = view.above[at] > 0;
        setColor(cr, lo && hi ? Rgb{0.55, 0.15, 0.6} : lo ? Rgb{0.1, 0.35, 0.85} : hi ? Rgb{0.85, 0.1, 0.1} : Rgb{0.85, 0.85, 0.85});
        cairo_rectangle(cr, x0 + u * bu, y0 - (v + 1) * bv, bu + 0.5, bv + 0.5);
        cairo_fill(cr);
      }
    setColor(cr, {0.2, 0.2, 0.2});
    label(cr, x0, kMargin - 12, title);
  };
  const double base = kMargin + 10 + std::max(yMm, zMm) * scale;
  drawView(top_, kMargin, base, voxelMm_[1], "top (x right, y up)");
  drawView(front_, kMargin + kGap + xMm * scale, base, voxelMm_[2], "front (x right, z up)");
  char legend[160];
  std::snprintf(legend, sizeof legend, "grey: part   blue: below the floor   red: above the stiffest mix   (bins of %d voxels)", bin_);
  label(cr, kMargin, height - 14, legend, 12);

  const std::string png = canvas.png({});
  return Bytes(png.begin(), png.end());
}

// ------------------------------------------------------------------------------------------ report.html

namespace {

std::string base64(const std::uint8_t* data, std::size_t size) {
  std::string out(4 * ((size + 2) / 3) + 1, '\0');
  // EVP_EncodeBlock takes an int length: encode in pieces (a multiple of 3 bytes, so no padding between).
  constexpr std::size_t kPiece = 3u << 20;
  std::size_t written = 0;
  for (std::size_t at = 0; at < size; at += kPiece) {
    const std::size_t n = std::min(kPiece, size - at);
    written += static_cast<std::size_t>(EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data() + written), data + at, static_cast<int>(n)));
  }
  out.resize(written);
  return out;
}

std::string pngDataUri(const Bytes& png) { return "data:image/png;base64," + base64(png.data(), png.size()); }

// Text made safe for HTML (also in attribute values); invalid UTF-8 (a design's odd file name) becomes U+FFFD.
std::string html(const std::string& raw) {
  const std::string text = json::parse(json(raw).dump(-1, ' ', false, json::error_handler_t::replace)).get<std::string>();
  return common::escapeMarkup(text);
}

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

std::string general(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

// 1234567 -> "1,234,567".
std::string count(std::uint64_t n) {
  std::string digits = std::to_string(n), out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

// A table row: header, value (already HTML), the value cell's id ("" for none).
std::string row(const std::string& header, const std::string& valueHtml, const std::string& id = "") {
  return "<tr><th>" + html(header) + "</th><td" + (id.empty() ? "" : " id=\"" + id + "\"") + ">" + valueHtml + "</td></tr>\n";
}

const json& need(const json& j, const char* key) {
  const auto it = j.find(key);
  if (it == j.end()) throw std::runtime_error(std::string("job report: the manifest lacks \"") + key + "\"");
  return *it;
}

constexpr const char* kStyle = R"(body{font-family:sans-serif;margin:24px auto;max-width:1100px;color:#222;line-height:1.4}
h1{margin-bottom:4px}h2{border-bottom:1px solid #ccc;padding-bottom:3px;margin-top:28px}
.sub{color:#555;margin-top:0}table{border-collapse:collapse;margin:8px 0}
th,td{text-align:left;padding:3px 12px 3px 0;vertical-align:top}td.n,th.n{text-align:right}
thead th{border-bottom:1px solid #999}tfoot td,tfoot th{border-top:1px solid #999}
.verdict{padding:10px 14px;border-radius:6px;font-weight:bold}.ok{background:#e3f4e1;border:1px solid #6a6}
.unknown{background:#fff4d6;border:1px solid #c93}.warn{background:#fff4d6;border:1px solid #c93;padding:8px 14px;border-radius:6px}
img{max-width:100%;border:1px solid #ddd;margin:6px 0}figure{margin:10px 0}figcaption{color:#555;font-size:90%}
code{background:#f3f3f3;padding:0 3px})";

std::string verdictSection(const json& m, bool verified) {
  std::uint64_t layerFiles = 0;
  for (const json& layer : need(m, "layers")) layerFiles += layer.at("files").size();
  std::string s = "<section id=\"checksums\"><h2>Checksums</h2>\n";
  if (verified)
    s += "<p class=\"verdict ok\" id=\"checksum-verdict\">Verified when written: every file of this job (" + count(layerFiles) +
         " layer images, the build file, the previews and this report) matched its size and XXH3-128 checksum in manifest.json; "
         "the images of one layer in " + std::to_string(printer_profiles::kVerifyDecodeEvery) +
         " and of the last decoded to the voxel counts and orientation the manifest records, and every other layer image was "
         "compared in its stored form with what was encoded. rodfab renames a job into place only after this check passes.</p>\n";
  else
    s += "<p class=\"verdict unknown\" id=\"checksum-verdict\">Not verified when written (verification was switched off): "
         "check the job before printing.</p>\n";
  s += "<p>After copying the job to another disk or machine, check it again with <code>rodfab inspect JOB</code>.</p></section>\n";
  return s;
}

std::string warningsSection(const std::vector<std::string>& warnings) {
  std::string s = "<section id=\"warnings\"><h2>Warnings</h2>\n";
  if (warnings.empty()) return s + "<p id=\"warning-count\">None.</p></section>\n";
  s += "<div class=\"warn\"><p id=\"warning-count\">" + count(warnings.size()) + " warning(s):</p><ul>\n";
  for (const std::string& w : warnings) s += "<li>" + html(w) + "</li>\n";
  return s + "</ul></div></section>\n";
}

std::string printSection(const json& m) {
  const json& profile = need(m, "profile");
  const json& image = need(m, "image");
  const json& frame = need(m, "frame");
  const int layers = need(m, "layer_count").get<int>();
  const double thickness = profile.at("layer_thickness_mm").get<double>();
  const json& size = frame.at("part_size_mm");
  std::string s = "<section id=\"print\"><h2>Print</h2><table>\n";
  s += row("Printer", html(profile.at("printer").get<std::string>()) + " (profile " + html(profile.at("name").get<std::string>()) + ")");
  s += row("Layers", count(static_cast<std::uint64_t>(layers)), "layer-count");
  s += row("Layer thickness", fixed(thickness * 1000.0, 1) + " &micro;m");
  s += row("Print height", fixed(layers * thickness, 2) + " mm", "print-height");
  s += row("Part size", fixed(size.at(0).get<double>(), 2) + " &times; " + fixed(size.at(1).get<double>(), 2) + " &times; " +
                            fixed(size.at(2).get<double>(), 2) + " mm (x &times; y &times; z)", "part-size");
  s += row("Layer images", count(image.at("width").get<std::uint64_t>()) + " &times; " + count(image.at("height").get<std::uint64_t>()) +
                               " px, 1-bit " + html(image.at("format").get<std::string>()));
  s += row("Model voxels", count(need(m, "statistics").at("model_voxels").get<std::uint64_t>()), "model-voxels");
  s += row("Support", html(need(m, "support").at("policy").get<std::string>()) + ": " + html(m["support"].at("note").get<std::string>()));
  return s + "</table></section>\n";
}

std::string materialsSection(const json& m) {
  std::string s = "<section id=\"materials\"><h2>Materials</h2><table>\n<thead><tr><th>material</th><th>role</th>"
                  "<th class=\"n\">voxels</th><th class=\"n\">volume</th><th class=\"n\">mass</th></tr></thead><tbody>\n";
  double volume = 0.0, mass = 0.0;
  for (const json& material : need(m, "materials")) {
    const std::string name = material.at("name").get<std::string>();
    const json& stat = need(m, "statistics").at("materials").at(name);
    volume += stat.at("volume_ml").get<double>();
    mass += stat.at("mass_g").get<double>();
    s += "<tr data-material=\"" + html(name) + "\"><td>" + html(name) + "</td><td>" + html(stat.at("role").get<std::string>()) +
         "</td><td class=\"n voxels\">" + count(stat.at("voxels").get<std::uint64_t>()) + "</td><td class=\"n volume\">" +
         fixed(stat.at("volume_ml").get<double>(), 3) + " mL</td><td class=\"n mass\">" + fixed(stat.at("mass_g").get<double>(), 3) +
         " g</td></tr>\n";
  }
  s += "</tbody><tfoot><tr><th>total</th><td></td><td></td><td class=\"n\" id=\"total-volume\">" + fixed(volume, 3) +
       " mL</td><td class=\"n\" id=\"total-mass\">" + fixed(mass, 3) + " g</td></tr></tfoot></table></section>\n";
  return s;
}

std::string previewsSection(const std::vector<std::pair<std::string, Bytes>>& previews) {
  std::string s = "<section id=\"previews\"><h2>Previews</h2>\n";
  for (const auto& [name, png] : previews)
    s += "<figure><img alt=\"" + html(name) + "\" data-file=\"" + html(name) + "\" src=\"" + pngDataUri(png) + "\"><figcaption>" +
         html(name) + "</figcaption></figure>\n";
  return s + "</section>\n";
}

std::string clampingSection(const json& m, const ClampMap* clamps) {
  std::string s = "<section id=\"clamping\"><h2>Clamped moduli</h2>\n";
  const json& c = need(m, "statistics").at("clamped_modulus");
  if (c.is_null()) return s + "<p>Not recorded for this job.</p></section>\n";
  const std::uint64_t below = c.at("below_floor_voxels").get<std::uint64_t>(), above = c.at("above_ceiling_voxels").get<std::uint64_t>();
  s += "<p>Voxels whose requested modulus the materials cannot make are printed at the nearest one they can.</p><table>\n";
  s += row("Below the floor (" + general(c.at("floor_mpa").get<double>()) + " MPa)", count(below) + " voxels, raised to the floor", "clamped-below");
  s += row("Above the stiffest mix (" + general(c.at("ceiling_mpa").get<double>()) + " MPa)", count(above) + " voxels, printed in pure rigid material",
           "clamped-above");
  s += "</table>\n";
  if (below + above == 0) return s + "<p id=\"clamp-verdict\">None: every voxel gets the modulus the design asks for.</p></section>\n";
  if (clamps) {
    s += "<figure><img alt=\"where the clamped voxels are\" src=\"" + pngDataUri(clamps->renderPng()) +
         "\"><figcaption>Where they are: <span id=\"located-below\">" + count(clamps->belowFloor()) +
         "</span> below the floor, <span id=\"located-above\">" + count(clamps->aboveMax()) + "</span> above the stiffest mix.</figcaption></figure>\n";
  }
  return s + "</section>\n";
}

std::string calibrationSection(const json& m, const ReportInputs& inputs) {
  std::string s = "<section id=\"calibration\"><h2>Calibration</h2>\n";
  const json& cal = need(m, "calibration");
  if (cal.is_null()) return s + "<p>None recorded.</p></section>\n";
  s += "<table>\n" + row("File", html(cal.at("file").get<std::string>()), "calibration-file");
  s += row("SHA-256", "<code>" + html(cal.at("sha256").get<std::string>()) + "</code>", "calibration-sha256");
  if (const calibration::Calibration* c = inputs.calibration) {
    s += row("Floor", general(c->floorMpa()) + " MPa at " + fixed(100.0 * c->floorFraction(), 1) + " % rigid");
    s += row("Stiffest mix", general(c->maxModulusMpa()) + " MPa (100 % rigid)");
    if (c->record().temperatureC) s += row("Measured at", fixed(*c->record().temperatureC, 0) + " &deg;C");
    s += "</table>\n";
    const std::string plot = calibration::renderFitPlot(*c);
    const Bytes png(plot.begin(), plot.end());
    s += "<figure><img alt=\"calibration fit\" src=\"" + pngDataUri(png) + "\"><figcaption>The calibration's fit: modulus against "
         "rigid (Vero) fraction.</figcaption></figure>\n";
  } else {
    s += "</table>\n";
  }
  return s + "</section>\n";
}

std::string ditheringSection(const json& m) {
  const json& d = need(m, "dithering");
  std::string s = "<section id=\"dithering\"><h2>Dithering</h2><table>\n";
  s += row("Ditherer", html(d.at("ditherer").get<std::string>()), "ditherer");
  s += row("Seed", std::to_string(d.at("seed").get<std::uint64_t>()), "seed");
  return s + "</table><p>The same design, calibration, profile, ditherer and seed give the same job, byte for byte.</p></section>\n";
}

}  // namespace

std::string renderJobReport(const json& manifest, const std::vector<std::pair<std::string, Bytes>>& previews, const ReportInputs& inputs) {
  try {
    const json& meta = manifest.contains("metadata") ? manifest["metadata"] : json::object();
    const std::string design = meta.value("design", std::string());
    std::string page = "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<meta name=\"generator\" content=\"rodfab\">\n";
    page += "<title>Job report: " + html(design.empty() ? "rodfab job" : design) + "</title>\n<style>" + kStyle + "</style></head><body>\n";
    page += "<h1>Job report</h1>\n<p class=\"sub\">";
    if (!design.empty()) page += "Design <b id=\"design\">" + html(design) + "</b>";
    if (meta.contains("design_sha256")) page += " (SHA-256 <code>" + html(meta["design_sha256"].get<std::string>()) + "</code>)";
    page += design.empty() ? "" : ", ";
    page += "made by rodfab. Read before printing.</p>\n";
    page += verdictSection(manifest, inputs.verified) + warningsSection(inputs.warnings) + printSection(manifest) +
            materialsSection(manifest) + previewsSection(previews) + clampingSection(manifest, inputs.clamps) +
            calibrationSection(manifest, inputs) + ditheringSection(manifest);
    return page + "</body></html>\n";
  } catch (const json::exception& e) {
    throw std::runtime_error(std::string("job report: the manifest is not as the writer makes it: ") + e.what());
  }
}

}  // namespace rodfab::slicer
