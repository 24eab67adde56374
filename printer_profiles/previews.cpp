#include "printer_profiles/previews.hpp"

#include "common/memory_budget.hpp"
#include "printer_profiles/preview_scan.hpp"

#include <cairo.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <array>
#include <initializer_list>
#include <cstring>
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <tuple>

namespace rodfab::printer_profiles {

namespace {

using preview_scan::kNoModulus;
using preview_scan::modulusAt;

constexpr std::uint8_t kBackground[3] = {196, 204, 216};
constexpr std::uint8_t kEmptyTile[3] = {230, 233, 238};

// Moduli the colour scale spans: finite and positive. Anything else a grid may hold (0, negative,
// infinite, NaN) is drawn grey as unknown, and never enters the scale's logarithms.
bool onScale(float e) { return std::isfinite(e) && e > 0.0f; }

// A perceptually ordered ramp, dark violet (soft) to yellow (stiff), by linear interpolation of five stops.
void modulusColour(double t, std::uint8_t out[3]) {
  static constexpr double kStops[5][3] = {{48, 18, 90}, {40, 84, 160}, {30, 150, 150}, {110, 200, 80}, {250, 225, 40}};
  if (!(t >= 0.0)) t = 0.0;  // NaN too: the index below must stay in the table
  t = std::min(t, 1.0) * 4.0;
  const int a = std::min(3, static_cast<int>(t));
  const double f = t - a;
  for (int c = 0; c < 3; ++c) out[c] = static_cast<std::uint8_t>(std::lround(kStops[a][c] * (1 - f) + kStops[a + 1][c] * f));
}

// Writes into a cairo ARGB32 surface (0xAARRGGBB native words).
void putPixel(cairo_surface_t* s, int x, int y, const std::uint8_t rgb[3], double shade = 1.0) {
  auto* row = reinterpret_cast<std::uint32_t*>(cairo_image_surface_get_data(s) + y * cairo_image_surface_get_stride(s));
  const auto ch = [&](int c) { return static_cast<std::uint32_t>(std::lround(std::clamp(rgb[c] * shade, 0.0, 255.0))); };
  row[x] = 0xff000000u | (ch(0) << 16) | (ch(1) << 8) | ch(2);
}

// The surface's pixels as an RGB PNG, converted a row at a time as the encoder takes them.
Bytes surfaceToPng(cairo_surface_t* s) {
  cairo_surface_flush(s);
  const int w = cairo_image_surface_get_width(s), h = cairo_image_surface_get_height(s);
  const unsigned char* data = cairo_image_surface_get_data(s);
  const int stride = cairo_image_surface_get_stride(s);
  return encodePngRgb(w, h, [&](int y, std::uint8_t* out) {
    const auto* row = reinterpret_cast<const std::uint32_t*>(data + static_cast<std::ptrdiff_t>(y) * stride);
    for (int x = 0; x < w; ++x, out += 3) {
      out[0] = static_cast<std::uint8_t>(row[x] >> 16);
      out[1] = static_cast<std::uint8_t>(row[x] >> 8);
      out[2] = static_cast<std::uint8_t>(row[x]);
    }
  });
}

void text(cairo_t* cr, double x, double y, const std::string& s, double size = 13.0) {
  cairo_set_font_size(cr, size);
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.12);
  cairo_move_to(cr, x, y);
  cairo_show_text(cr, s.c_str());
}

std::string format(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

// Owns a cairo surface and context for one preview image, the data limit lifted meanwhile (cairo cannot
// survive a failed allocation; a preview's size is bounded: Previews::heldBytesAtMost).
struct Canvas {
  common::DataLimitLifted lifted;
  cairo_surface_t* surface;
  cairo_t* cr;
  Canvas(int w, int h) : surface(cairo_image_surface_create(CAIRO_FORMAT_ARGB32, w, h)), cr(cairo_create(surface)) {
    cairo_set_source_rgb(cr, 0.97, 0.97, 0.98);
    cairo_paint(cr);
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_surface_flush(surface);
  }
  ~Canvas() {
    cairo_destroy(cr);
    cairo_surface_destroy(surface);
  }
  Canvas(const Canvas&) = delete;
  Canvas& operator=(const Canvas&) = delete;
};

constexpr int kMargin = 24;  // pixels around the drawings

// Where the three views go on the projections' canvas, in pixels, and its scale (pixels per mm).
struct ProjectionLayout {
  double scale = 0.0, xMm = 0.0;  // the part's extent along x, mm
  int margin = kMargin, gap = 56, header = 84;
  int topW = 0, topH = 0, frontH = 0, sideW = 0, width = 0, height = 0;
  int topX = 0, topY = 0, frontY = 0, sideX = 0;
};

ProjectionLayout projectionLayout(const JobGeometry& g, const std::array<double, 3>& vx) {
  ProjectionLayout l;
  l.xMm = g.width * vx[0];
  const double yMm = g.height * vx[1], zMm = g.layers * vx[2];
  // Pixels per mm: the third-angle layout (top above front, side right of front) fits ~1400 x 1000.
  l.scale = std::min({1400.0 / (l.xMm + yMm), 1000.0 / (yMm + zMm), 60.0});
  const auto px = [&](double mmLength) { return std::max(1, static_cast<int>(std::lround(mmLength * l.scale))); };
  l.topW = px(l.xMm), l.topH = px(yMm), l.frontH = px(zMm), l.sideW = px(yMm);
  l.width = std::max(l.margin * 2 + l.topW + l.gap + l.sideW, 720);
  l.height = l.header + l.topH + l.gap + l.frontH + l.margin + 40;
  l.topX = l.margin, l.topY = l.header, l.frontY = l.header + l.topH + l.gap, l.sideX = l.margin + l.topW + l.gap;
  return l;
}

// The range of the moduli the views show, for their log colour scale.
struct ModulusScale {
  bool known = false;  // some voxel of the views has a modulus on the scale
  float min = std::numeric_limits<float>::max(), max = 0.0f;
  double logMin = 0.0, logSpan = 1.0;
};

template <class ViewT>
ModulusScale modulusScale(bool haveModulus, std::initializer_list<const ViewT*> views) {
  ModulusScale s;
  for (const ViewT* v : views)
    for (float e : v->modulus)
      if (onScale(e)) {
        s.min = std::min(s.min, e);
        s.max = std::max(s.max, e);
      }
  s.known = haveModulus && s.max > 0.0f;
  if (s.known) s.logMin = std::log(s.min), s.logSpan = std::log(s.max) - s.logMin;
  return s;
}

// How a view's axes run on the image: u to the right and v down, or reversed.
struct ViewAxes {
  bool uLeftward = false, vUpward = false;
};

// Colours one view's pixels (as many as its axes sample) at (ox, oy): by material, or by modulus on
// `byModulus`'s scale when given, shaded by depth. Each pixel shows the cell its axes sample there.
template <class ViewT>
void drawView(cairo_surface_t* surface, const ViewT& view, int ox, int oy, ViewAxes axes, int depthRange,
              const ModulusScale* byModulus, const ProfileMaterial& rigid, const ProfileMaterial& rubbery) {
  const int w = view.u.pixels(), h = view.v.pixels();
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t at = view.at(view.u.cellOfPixel(axes.uLeftward ? w - 1 - x : x), view.v.cellOfPixel(axes.vUpward ? h - 1 - y : y));
      const std::uint8_t m = view.material[at];
      if (!m) {
        putPixel(surface, ox + x, oy + y, kBackground);
        continue;
      }
      const double shade = 0.55 + 0.45 * (depthRange > 1 ? static_cast<double>(view.depth[at]) / (depthRange - 1) : 1.0);
      std::uint8_t rgb[3] = {};  // set below; zeroed so no compiler sees it read unset
      if (byModulus) {
        const float e = view.modulus[at];
        if (onScale(e)) modulusColour(byModulus->logSpan > 0 ? (std::log(e) - byModulus->logMin) / byModulus->logSpan : 1.0, rgb);
        else rgb[0] = rgb[1] = rgb[2] = 128;
      } else {
        const auto& c = (m == 1 ? rigid : rubbery).previewRgb;
        std::copy(c.begin(), c.end(), rgb);
      }
      putPixel(surface, ox + x, oy + y, rgb, m == 2 && !byModulus ? 0.6 + 0.4 * shade : shade);
    }
}

// The title, the views' captions and a 10 mm scale bar (1 mm for small parts) under the front view.
void drawCaptions(cairo_t* cr, const ProjectionLayout& l, const std::string& title, bool byModulus) {
  text(cr, l.margin, 26, title, 16);
  text(cr, l.margin, 48,
       std::string(byModulus ? "coloured by Young's modulus (log scale)" : "coloured by material") +
           "; shaded by depth (brighter = nearer); to scale, " + format("%.1f", 10.0 * l.scale) + " px per cm",
       12);
  text(cr, l.topX, l.topY - 6, "top (looking down: x right, y up)", 12);
  text(cr, l.topX, l.frontY - 6, "front (looking along +y: x right, z up)", 12);
  text(cr, l.sideX, l.frontY - 6, "right side (looking along -x: y right, z up)", 12);
  const double barMm = l.xMm >= 20 ? 10.0 : 1.0;
  const double barY = l.frontY + l.frontH + 20;
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.12);
  cairo_rectangle(cr, l.topX, barY, barMm * l.scale, 4);
  cairo_fill(cr);
  text(cr, l.topX + barMm * l.scale + 8, barY + 7, format("%.0f mm", barMm), 12);
}

// The legend to the right of the top view: the modulus ramp with its ends, or the two materials.
void drawLegend(cairo_t* cr, const ProjectionLayout& l, const ModulusScale* byModulus, const ProfileMaterial& rigid,
                const ProfileMaterial& rubbery) {
  double ly = l.topY + 8;
  const double lx = l.sideX;
  if (byModulus) {
    for (int i = 0; i < 120; ++i) {
      std::uint8_t rgb[3] = {};  // set below; zeroed so no compiler sees it read unset
      modulusColour(i / 119.0, rgb);
      cairo_set_source_rgb(cr, rgb[0] / 255.0, rgb[1] / 255.0, rgb[2] / 255.0);
      cairo_rectangle(cr, lx + i * 2, ly, 2, 14);
      cairo_fill(cr);
    }
    text(cr, lx, ly + 30, format("%.3g MPa", byModulus->min), 12);
    text(cr, lx + 200, ly + 30, format("%.3g MPa", byModulus->max), 12);
    return;
  }
  for (const ProfileMaterial* m : {&rigid, &rubbery}) {
    cairo_set_source_rgb(cr, m->previewRgb[0] / 255.0, m->previewRgb[1] / 255.0, m->previewRgb[2] / 255.0);
    cairo_rectangle(cr, lx, ly, 16, 16);
    cairo_fill_preserve(cr);
    cairo_set_source_rgb(cr, 0.3, 0.3, 0.3);
    cairo_set_line_width(cr, 1);
    cairo_stroke(cr);
    text(cr, lx + 24, ly + 13, m->name + " (" + toString(m->role) + ")", 12);
    ly += 24;
  }
}

}  // namespace

AxisSamples::AxisSamples(int cells, int pixels)
    : cells_(cells), pixels_(pixels), slots_(static_cast<std::size_t>(cells), -1), hidden_((static_cast<std::size_t>(cells) + 7) / 8, 0xff) {
  for (int p = 0; p < pixels; ++p) {
    const int c = cellOfPixel(p);  // never decreases with p: slots follow the cells' order
    if (slots_[static_cast<std::size_t>(c)] >= 0) continue;
    slots_[static_cast<std::size_t>(c)] = kept_++;
    hidden_[static_cast<std::size_t>(c) / 8] = static_cast<std::uint8_t>(hidden_[static_cast<std::size_t>(c) / 8] & ~(0x80u >> (c % 8)));
  }
}

// The same arithmetic as the views' drawing always used (double, then truncated and clamped).
int AxisSamples::cellOfPixel(int p) const { return std::clamp(static_cast<int>((p + 0.5) * cells_ / pixels_), 0, cells_ - 1); }

Previews::View::View(AxisSamples us, AxisSamples vs) : u(std::move(us)), v(std::move(vs)), width(u.kept()), height(v.kept()) {
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  material.assign(n, 0);
  depth.assign(n, -1);
  modulus.assign(n, kNoModulus);
}

namespace {

// The layers on the contact sheet: `wanted` (at least 1) evenly spaced, first and last included.
std::vector<int> contactLayersOf(int layers, int wanted) {
  std::vector<int> out;
  const int n = std::clamp(wanted, 1, layers);
  for (int s = 0; s < n; ++s)
    out.push_back(n == 1 ? layers / 2 : static_cast<int>(std::lround(static_cast<double>(s) * (layers - 1) / (n - 1))));
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

// A contact tile's pixels (width, height): the layer's aspect in millimetres, fitting a 300-pixel box.
std::pair<int, int> contactTileSize(const JobGeometry& g, const std::array<double, 3>& vx) {
  const double wMm = g.width * vx[0], hMm = g.height * vx[1];
  const double scale = 300.0 / std::max(wMm, hMm);
  return {std::max(1, static_cast<int>(std::lround(wMm * scale))), std::max(1, static_cast<int>(std::lround(hMm * scale)))};
}

// Bytes a view's cell holds: material, depth, modulus (Previews::View).
constexpr std::size_t kViewCellBytes = sizeof(std::uint8_t) + sizeof(std::int32_t) + sizeof(float);

}  // namespace

Previews::Previews(const JobGeometry& geometry, const Profile& profile, int contactSheetLayers)
    : geometry_(geometry), profile_(profile) {
  const ProjectionLayout l = projectionLayout(geometry, profile.voxelSizeMm);
  const AxisSamples columns(geometry.width, l.topW), layers(geometry.layers, l.frontH);
  top_ = View(columns, AxisSamples(geometry.height, l.topH));
  front_ = View(columns, layers);
  side_ = View(AxisSamples(geometry.height, l.sideW), layers);
  contactLayers_ = contactLayersOf(geometry.layers, contactSheetLayers);
  std::tie(tileWidth_, tileHeight_) = contactTileSize(geometry, profile.voxelSizeMm);
  tiles_.resize(contactLayers_.size());
}

std::size_t Previews::heldBytesAtMost(const JobGeometry& geometry, const Profile& profile, int contactSheetLayers) {
  const ProjectionLayout l = projectionLayout(geometry, profile.voxelSizeMm);
  // An axis of `cells` drawn in `pixels` keeps min(cells, pixels) cells (AxisSamples: each pixel shows
  // one cell, neighbouring pixels never skip a cell when there are more pixels than cells).
  const auto kept = [](int cells, int pixels) { return static_cast<std::size_t>(std::min(cells, pixels)); };
  const std::size_t columns = kept(geometry.width, l.topW), layers = kept(geometry.layers, l.frontH);
  const std::size_t cells =
      columns * kept(geometry.height, l.topH) + columns * layers + kept(geometry.height, l.sideW) * layers;
  const auto [tileWidth, tileHeight] = contactTileSize(geometry, profile.voxelSizeMm);
  const std::size_t tiles = contactLayersOf(geometry.layers, contactSheetLayers).size();
  return kViewCellBytes * cells + tiles * static_cast<std::size_t>(tileWidth) * static_cast<std::size_t>(tileHeight);
}

std::size_t Previews::memoryBytes() const {
  std::size_t bytes = 0;
  for (const View* v : {&top_, &front_, &side_})
    bytes += v->material.size() * sizeof(v->material[0]) + v->depth.size() * sizeof(v->depth[0]) + v->modulus.size() * sizeof(v->modulus[0]);
  for (const auto& t : tiles_) bytes += t.size();
  return bytes;
}

namespace {

// Whether bytes [at, at + 8) of both rows are empty: layers are mostly empty, so scans skip a word at a time.
bool emptyWord(const std::uint8_t* a, const std::uint8_t* b, std::size_t at) {
  std::uint64_t x, y;
  std::memcpy(&x, a + at, 8);
  std::memcpy(&y, b + at, 8);
  return !(x | y);
}

}  // namespace

void Previews::addLayer(int layer, const LayerBitmaps& b, const openvdb::FloatGrid* modulus) {
  if (front_.v.slot(layer) >= 0) addFrontAndSide(layer, b, modulus);  // both views show the same layers
  addContactTile(layer, b);
}

void Previews::addFrontAndSide(int layer, const LayerBitmaps& b, const openvdb::FloatGrid* modulus) {
  std::optional<openvdb::FloatGrid::ConstAccessor> acc;
  if (modulus) acc.emplace(modulus->getConstAccessor());
  const int h = geometry_.height, k = geometry_.k(layer);
  const auto modulusOf = [&](int c, int r) { return modulusAt(modulus, acc ? &*acc : nullptr, {geometry_.i(c), geometry_.j(r), k}); };
  // Front view: looking along +y, the visible voxel of a column has the smallest y (largest row).
  // `claimed` marks the columns a lower row already showed (and those no pixel shows), so each column
  // is decided once; the scan ends when every shown column is decided.
  std::vector<std::uint8_t> claimed = front_.u.hiddenMask();
  int undecided = front_.u.kept();
  for (int r = h - 1; r >= 0 && undecided > 0; --r) {
    const RowSpan span = b.span(r);
    if (span.empty()) continue;
    preview_scan::forEachFreshInRow(b, r, claimed.data(), [&](int c, bool isRigid) {
      --undecided;
      front_.set(front_.at(c, layer), isRigid, r, modulusOf(c, r));
    });
  }
  // Right side view: looking along -x, the visible voxel of a row has the largest x (last column).
  for (int r = 0; r < h; ++r) {
    const RowSpan span = b.span(r);
    if (side_.u.slot(r) < 0 || span.empty()) continue;
    const std::uint8_t* rigid = b.rigid().row(r);
    const std::uint8_t* rubbery = b.rubbery().row(r);
    for (std::size_t byte = span.end; byte-- > span.begin;) {
      if (byte >= span.begin + 7 && byte % 8 == 7 && emptyWord(rigid, rubbery, byte - 7)) {
        byte -= 7;
        continue;
      }
      const std::uint8_t any = rigid[byte] | rubbery[byte];
      if (!any) continue;
      const int bit = 7 - std::countr_zero(any);
      const int c = static_cast<int>(byte) * 8 + bit;
      side_.set(side_.at(r, layer), ((rigid[byte] >> (7 - bit)) & 1) != 0, c, modulusOf(c, r));
      break;
    }
  }
}

void Previews::addContactTile(int layer, const LayerBitmaps& b) {
  const int w = geometry_.width, h = geometry_.height;
  const auto slot = std::find(contactLayers_.begin(), contactLayers_.end(), layer);
  if (slot == contactLayers_.end()) return;
  std::vector<std::uint8_t>& tile = tiles_[static_cast<std::size_t>(slot - contactLayers_.begin())];
  tile.assign(static_cast<std::size_t>(tileWidth_) * tileHeight_, 0);
  for (int y = 0; y < tileHeight_; ++y) {
    const int r = std::min(h - 1, static_cast<int>((y + 0.5) * h / tileHeight_));
    for (int x = 0; x < tileWidth_; ++x) {
      const int c = std::min(w - 1, static_cast<int>((x + 0.5) * w / tileWidth_));
      std::uint8_t code = 0;
      if (b.rigid().get(c, r)) code = 1;
      else if (b.rubbery().get(c, r)) code = 2;
      else if (b.hasSupport && b.support.get(c, r)) code = 3;
      tile[static_cast<std::size_t>(y) * tileWidth_ + x] = code;
    }
  }
}

namespace {

// The top, front and right side views on one image (third-angle layout, to scale), coloured by
// material or, with `byModulus`, by modulus; captions, scale bar and legend.
template <class ViewT>
Bytes renderProjections(const std::string& title, const JobGeometry& g, const Profile& profile, const ViewT& top,
                        const ViewT& front, const ViewT& side, const ModulusScale* byModulus) {
  const ProjectionLayout l = projectionLayout(g, profile.voxelSizeMm);
  const ProfileMaterial& rigid = profile.material(MaterialRole::Rigid);
  const ProfileMaterial& rubbery = profile.material(MaterialRole::Rubbery);
  Canvas canvas(l.width, l.height);
  // Top: x to the right, y up (image rows already run from the largest y down).
  drawView(canvas.surface, top, l.topX, l.topY, {}, g.layers, byModulus, rigid, rubbery);
  // Front: x to the right, z up; shade by nearness (larger row = nearer the viewer).
  drawView(canvas.surface, front, l.topX, l.frontY, {.vUpward = true}, g.height, byModulus, rigid, rubbery);
  // Right side: y to the right, z up; shade by nearness (larger column = nearer the viewer). Image row
  // 0 is the largest y, so y to the right runs from the last row to the first.
  drawView(canvas.surface, side, l.sideX, l.frontY, {.uLeftward = true, .vUpward = true}, g.width, byModulus, rigid, rubbery);
  cairo_surface_mark_dirty(canvas.surface);
  drawCaptions(canvas.cr, l, title, byModulus != nullptr);
  drawLegend(canvas.cr, l, byModulus, rigid, rubbery);
  return surfaceToPng(canvas.surface);
}

// The contact sheet: the evenly spaced `layers` (their tiles, tileWidth x tileHeight
// codes: 0 empty, 1 rigid, 2 rubbery, 3 support), four per row, as seen from above.
Bytes renderContactSheet(const std::string& title, const Profile& profile, const std::vector<int>& layers,
                         const std::vector<std::vector<std::uint8_t>>& tiles, int tileWidth, int tileHeight) {
  const ProfileMaterial& rigid = profile.material(MaterialRole::Rigid);
  const ProfileMaterial& rubbery = profile.material(MaterialRole::Rubbery);
  const ProfileMaterial& support = profile.material(MaterialRole::Support);
  const int margin = kMargin;
  const int columns = std::min<int>(4, static_cast<int>(layers.size()));
  const int rows = (static_cast<int>(layers.size()) + columns - 1) / columns;
  const int cellW = tileWidth + 24, cellH = tileHeight + 40;
  const int sheetW = std::max(margin * 2 + columns * cellW, 560), sheetH = 64 + rows * cellH + margin;
  Canvas sheet(sheetW, sheetH);
  for (std::size_t s = 0; s < layers.size(); ++s) {
    const int ox = margin + static_cast<int>(s % columns) * cellW, oy = 64 + static_cast<int>(s / columns) * cellH + 20;
    const std::vector<std::uint8_t>& tile = tiles[s];
    for (int y = 0; y < tileHeight; ++y)
      for (int x = 0; x < tileWidth; ++x) {
        const std::uint8_t code = tile.empty() ? 0 : tile[static_cast<std::size_t>(y) * tileWidth + x];
        const std::uint8_t* rgb = code == 1 ? rigid.previewRgb.data()
                                  : code == 2 ? rubbery.previewRgb.data()
                                  : code == 3 ? support.previewRgb.data()
                                              : kEmptyTile;
        putPixel(sheet.surface, ox + x, oy + y, rgb);
      }
  }
  cairo_surface_mark_dirty(sheet.surface);
  text(sheet.cr, margin, 26, title, 16);
  text(sheet.cr, margin, 48,
       "layers seen from above (x right, y up): " + rigid.name + " light, " + rubbery.name + " dark, " + support.name +
           " amber",
       12);
  for (std::size_t s = 0; s < layers.size(); ++s) {
    const int ox = margin + static_cast<int>(s % columns) * cellW, oy = 64 + static_cast<int>(s / columns) * cellH + 14;
    text(sheet.cr, ox, oy, "layer " + std::to_string(layers[s]) + "  z " +
                               format("%.2f mm", layers[s] * profile.voxelSizeMm[2]), 12);
  }
  return surfaceToPng(sheet.surface);
}

}  // namespace

std::vector<std::pair<std::string, Bytes>> Previews::render(const std::string& title) const {
  std::vector<std::pair<std::string, Bytes>> out;
  const ModulusScale modulus = modulusScale(haveModulus_, {&top_, &front_, &side_});
  const auto projections = [&](const ModulusScale* byModulus) {
    return renderProjections(title, geometry_, profile_, top_, front_, side_, byModulus);
  };
  // Each image on its own surface, drawn and compressed at once on the caller's arena (the PNGs' zlib
  // compression was most of finalize()'s serial time until round 10 compressed them with igzip).
  Bytes material, byModulus, sheet;
  tbb::parallel_invoke([&] { material = projections(nullptr); },
                       [&] {
                         if (modulus.known) byModulus = projections(&modulus);
                       },
                       [&] { sheet = renderContactSheet(title, profile_, contactLayers_, tiles_, tileWidth_, tileHeight_); });
  out.emplace_back("previews/projections-material.png", std::move(material));
  if (modulus.known) out.emplace_back("previews/projections-modulus.png", std::move(byModulus));
  out.emplace_back("previews/contact-sheet.png", std::move(sheet));
  return out;
}

}  // namespace rodfab::printer_profiles
