#include "printer_profiles/previews.hpp"

#include <cairo.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstring>
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>

namespace rodfab::printer_profiles {

namespace {

constexpr float kNoModulus = std::numeric_limits<float>::quiet_NaN();
constexpr std::uint8_t kBackground[3] = {196, 204, 216};
constexpr std::uint8_t kEmptyTile[3] = {230, 233, 238};

float modulusAt(const openvdb::FloatGrid* grid, openvdb::FloatGrid::ConstAccessor* acc, const openvdb::Coord& ijk) {
  if (!grid || !acc) return kNoModulus;
  float v = 0.0f;
  return acc->probeValue(ijk, v) ? v : kNoModulus;
}

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

Bytes surfaceToPng(cairo_surface_t* s) {
  cairo_surface_flush(s);
  const int w = cairo_image_surface_get_width(s), h = cairo_image_surface_get_height(s);
  RgbImage image(w, h, 0, 0, 0);
  for (int y = 0; y < h; ++y) {
    const auto* row = reinterpret_cast<const std::uint32_t*>(cairo_image_surface_get_data(s) + y * cairo_image_surface_get_stride(s));
    for (int x = 0; x < w; ++x) {
      std::uint8_t* p = image.at(x, y);
      p[0] = static_cast<std::uint8_t>(row[x] >> 16);
      p[1] = static_cast<std::uint8_t>(row[x] >> 8);
      p[2] = static_cast<std::uint8_t>(row[x]);
    }
  }
  return encodePngRgb(image);
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

// Owns a cairo surface and context for one preview image.
struct Canvas {
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

}  // namespace

void Previews::View::resize(int w, int h) {
  width = w;
  height = h;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  material.assign(n, 0);
  depth.assign(n, -1);
  modulus.assign(n, kNoModulus);
}

Previews::Previews(const JobGeometry& geometry, const Profile& profile, int contactSheetLayers)
    : geometry_(geometry), profile_(profile) {
  top_.resize(geometry.width, geometry.height);
  front_.resize(geometry.width, geometry.layers);
  side_.resize(geometry.height, geometry.layers);
  const int n = std::clamp(contactSheetLayers, 1, geometry.layers);
  for (int s = 0; s < n; ++s)
    contactLayers_.push_back(n == 1 ? geometry.layers / 2
                                    : static_cast<int>(std::lround(static_cast<double>(s) * (geometry.layers - 1) / (n - 1))));
  contactLayers_.erase(std::unique(contactLayers_.begin(), contactLayers_.end()), contactLayers_.end());
  // Tiles keep the layer's aspect in millimetres and fit a 300-pixel box.
  const double wMm = geometry.width * profile.voxelSizeMm[0], hMm = geometry.height * profile.voxelSizeMm[1];
  const double scale = 300.0 / std::max(wMm, hMm);
  tileWidth_ = std::max(1, static_cast<int>(std::lround(wMm * scale)));
  tileHeight_ = std::max(1, static_cast<int>(std::lround(hMm * scale)));
  tiles_.resize(contactLayers_.size());
}

namespace {

// Whether bytes [at, at + 8) of both rows are empty: layers are mostly empty, so scans skip a word at a time.
bool emptyWord(const std::uint8_t* a, const std::uint8_t* b, std::size_t at) {
  std::uint64_t x, y;
  std::memcpy(&x, a + at, 8);
  std::memcpy(&y, b + at, 8);
  return !(x | y);
}

// Calls visit(byte, bits) for the pixels of a row (rigid or rubbery) not yet in `claimed`, one byte
// of 8 pixels at a time, and adds them to `claimed`: a view decides each of its pixels once. Skips a
// word at a time where there is nothing new (layers are mostly empty, columns soon claimed).
template <class Visit>
void forEachFresh(const std::uint8_t* rigid, const std::uint8_t* rubbery, std::uint8_t* claimed, std::size_t stride, Visit&& visit) {
  for (std::size_t at = 0; at < stride; at += 8) {
    const std::size_t n = std::min<std::size_t>(8, stride - at);
    std::uint64_t a = 0, b = 0, c = 0;
    std::memcpy(&a, rigid + at, n);
    std::memcpy(&b, rubbery + at, n);
    std::memcpy(&c, claimed + at, n);
    if (!((a | b) & ~c)) continue;
    for (std::size_t byte = at; byte < at + n; ++byte) {
      const auto fresh = static_cast<unsigned>((rigid[byte] | rubbery[byte]) & ~claimed[byte] & 0xffu);
      if (!fresh) continue;
      claimed[byte] = static_cast<std::uint8_t>(claimed[byte] | fresh);
      visit(byte, fresh);
    }
  }
}

}  // namespace

void Previews::addLayer(int layer, const LayerBitmaps& b, const openvdb::FloatGrid* modulus) {
  std::optional<openvdb::FloatGrid::ConstAccessor> acc;
  if (modulus) acc.emplace(modulus->getConstAccessor());
  const int w = geometry_.width, h = geometry_.height;
  const int k = geometry_.k(layer);
  // Front view: looking along +y, the visible voxel of a column has the smallest y (largest row).
  // `claimed` marks the columns a lower row already showed, so each column is decided once.
  std::vector<std::uint8_t> claimed(b.rigid.stride(), 0);
  for (int r = h - 1; r >= 0; --r) {
    const std::uint8_t* rigid = b.rigid.row(r);
    const std::uint8_t* rubbery = b.rubbery.row(r);
    forEachFresh(rigid, rubbery, claimed.data(), b.rigid.stride(), [&](std::size_t byte, unsigned fresh) {
      for (; fresh; fresh &= fresh - 1) {
        const int bit = 7 - std::countr_zero(fresh);
        const int c = static_cast<int>(byte) * 8 + bit;
        const std::size_t at = static_cast<std::size_t>(layer) * w + c;
        front_.material[at] = ((rigid[byte] >> (7 - bit)) & 1) ? 1 : 2;
        front_.depth[at] = r;
        front_.modulus[at] = modulusAt(modulus, acc ? &*acc : nullptr, {geometry_.i(c), geometry_.j(r), k});
      }
    });
  }
  // Right side view: looking along -x, the visible voxel of a row has the largest x (last column).
  for (int r = 0; r < h; ++r) {
    const std::uint8_t* rigid = b.rigid.row(r);
    const std::uint8_t* rubbery = b.rubbery.row(r);
    for (std::size_t byte = b.rigid.stride(); byte-- > 0;) {
      if (byte % 8 == 7 && emptyWord(rigid, rubbery, byte - 7)) {
        byte -= 7;
        continue;
      }
      const std::uint8_t any = rigid[byte] | rubbery[byte];
      if (!any) continue;
      const int bit = 7 - std::countr_zero(any);
      const int c = static_cast<int>(byte) * 8 + bit;
      const std::size_t at = static_cast<std::size_t>(layer) * h + r;
      side_.material[at] = ((rigid[byte] >> (7 - bit)) & 1) ? 1 : 2;
      side_.depth[at] = c;
      side_.modulus[at] = modulusAt(modulus, acc ? &*acc : nullptr, {geometry_.i(c), geometry_.j(r), k});
      break;
    }
  }
  const auto slot = std::find(contactLayers_.begin(), contactLayers_.end(), layer);
  if (slot == contactLayers_.end()) return;
  std::vector<std::uint8_t>& tile = tiles_[static_cast<std::size_t>(slot - contactLayers_.begin())];
  tile.assign(static_cast<std::size_t>(tileWidth_) * tileHeight_, 0);
  for (int y = 0; y < tileHeight_; ++y) {
    const int r = std::min(h - 1, static_cast<int>((y + 0.5) * h / tileHeight_));
    for (int x = 0; x < tileWidth_; ++x) {
      const int c = std::min(w - 1, static_cast<int>((x + 0.5) * w / tileWidth_));
      std::uint8_t code = 0;
      if (b.rigid.get(c, r)) code = 1;
      else if (b.rubbery.get(c, r)) code = 2;
      else if (b.hasSupport && b.support.get(c, r)) code = 3;
      tile[static_cast<std::size_t>(y) * tileWidth_ + x] = code;
    }
  }
}

void Previews::addTopLayers(int first, const std::vector<LayerBitmaps>& layers, const openvdb::FloatGrid* modulus) {
  if (modulus) haveModulus_ = true;
  const int w = geometry_.width;
  tbb::parallel_for(tbb::blocked_range<int>(0, geometry_.height), [&](const tbb::blocked_range<int>& rows) {
    std::optional<openvdb::FloatGrid::ConstAccessor> acc;
    if (modulus) acc.emplace(modulus->getConstAccessor());
    std::vector<std::uint8_t> claimed;
    for (int r = rows.begin(); r != rows.end(); ++r) {
      // Layers from the band's top down: the first one seen in a column is its top within the band,
      // and replaces what earlier bands left (their layers are below `first`). `claimed` marks the
      // columns a higher layer of this band already took.
      claimed.assign(layers.empty() ? 0 : layers[0].rigid.stride(), 0);
      for (std::size_t n = layers.size(); n-- > 0;) {
        const std::uint8_t* rigid = layers[n].rigid.row(r);
        const std::uint8_t* rubbery = layers[n].rubbery.row(r);
        const int layer = first + static_cast<int>(n);
        forEachFresh(rigid, rubbery, claimed.data(), layers[n].rigid.stride(), [&](std::size_t byte, unsigned fresh) {
          for (; fresh; fresh &= fresh - 1) {
            const int bit = 7 - std::countr_zero(fresh);
            const int c = static_cast<int>(byte) * 8 + bit;
            const std::size_t at = static_cast<std::size_t>(r) * w + c;
            top_.material[at] = ((rigid[byte] >> (7 - bit)) & 1) ? 1 : 2;
            top_.depth[at] = layer;
            if (modulus) top_.modulus[at] = modulusAt(modulus, &*acc, {geometry_.i(c), geometry_.j(r), geometry_.k(layer)});
          }
        });
      }
    }
  });
}

std::vector<std::pair<std::string, Bytes>> Previews::render(const std::string& title) const {
  std::vector<std::pair<std::string, Bytes>> out;
  const auto& vx = profile_.voxelSizeMm;
  const double xMm = geometry_.width * vx[0], yMm = geometry_.height * vx[1], zMm = geometry_.layers * vx[2];
  // Pixels per mm: the third-angle layout (top above front, side right of front) fits ~1400 x 1000.
  const double scale = std::min({1400.0 / (xMm + yMm), 1000.0 / (yMm + zMm), 60.0});
  const int gap = 56, margin = 24, header = 84;
  const auto px = [&](double mmLength) { return std::max(1, static_cast<int>(std::lround(mmLength * scale))); };
  const int topW = px(xMm), topH = px(yMm), frontH = px(zMm), sideW = px(yMm);
  const int width = std::max(margin * 2 + topW + gap + sideW, 720);
  const int height = header + topH + gap + frontH + margin + 40;

  const ProfileMaterial& rigid = profile_.material(MaterialRole::Rigid);
  const ProfileMaterial& rubbery = profile_.material(MaterialRole::Rubbery);
  const ProfileMaterial& support = profile_.material(MaterialRole::Support);

  float eMin = std::numeric_limits<float>::max(), eMax = 0.0f;
  for (const View* v : {&top_, &front_, &side_})
    for (float e : v->modulus)
      if (onScale(e)) {
        eMin = std::min(eMin, e);
        eMax = std::max(eMax, e);
      }
  const bool modulusKnown = haveModulus_ && eMax > 0.0f;
  const double logMin = modulusKnown ? std::log(eMin) : 0.0, logSpan = modulusKnown ? std::log(eMax) - logMin : 1.0;

  for (int byModulus = 0; byModulus < (modulusKnown ? 2 : 1); ++byModulus) {
    Canvas canvas(width, height);
    // One view: (u, v) in view pixels -> voxel cell of the view's map, v = 0 at the top of the drawing.
    const auto drawView = [&](const View& view, int ox, int oy, int w, int h, int depthRange, auto cellOf) {
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const auto [cx, cy] = cellOf(x, y, w, h);
          const std::size_t at = static_cast<std::size_t>(cy) * view.width + cx;
          const std::uint8_t m = view.material[at];
          if (!m) {
            putPixel(canvas.surface, ox + x, oy + y, kBackground);
            continue;
          }
          const double shade = 0.55 + 0.45 * (depthRange > 1 ? static_cast<double>(view.depth[at]) / (depthRange - 1) : 1.0);
          std::uint8_t rgb[3];
          if (byModulus) {
            const float e = view.modulus[at];
            if (onScale(e)) modulusColour(logSpan > 0 ? (std::log(e) - logMin) / logSpan : 1.0, rgb);
            else rgb[0] = rgb[1] = rgb[2] = 128;
          } else {
            const auto& c = (m == 1 ? rigid : rubbery).previewRgb;
            std::copy(c.begin(), c.end(), rgb);
          }
          putPixel(canvas.surface, ox + x, oy + y, rgb, m == 2 && !byModulus ? 0.6 + 0.4 * shade : shade);
        }
    };
    const int topX = margin, topY = header, frontY = header + topH + gap, sideX = margin + topW + gap;
    const auto clampCell = [](double v, int n) { return std::clamp(static_cast<int>(v), 0, n - 1); };
    // Top: x to the right, y up (image rows already run from the largest y down).
    drawView(top_, topX, topY, topW, topH, geometry_.layers, [&](int x, int y, int w, int h) {
      return std::pair{clampCell((x + 0.5) * geometry_.width / w, geometry_.width), clampCell((y + 0.5) * geometry_.height / h, geometry_.height)};
    });
    // Front: x to the right, z up; shade by nearness (larger row = nearer the viewer).
    drawView(front_, topX, frontY, topW, frontH, geometry_.height, [&](int x, int y, int w, int h) {
      return std::pair{clampCell((x + 0.5) * geometry_.width / w, geometry_.width),
                       clampCell((h - 1 - y + 0.5) * geometry_.layers / h, geometry_.layers)};
    });
    // Right side: y to the right, z up; shade by nearness (larger column = nearer the viewer).
    drawView(side_, sideX, frontY, sideW, frontH, geometry_.width, [&](int x, int y, int w, int h) {
      // Image row 0 is the largest y, so y to the right runs from the last row to the first.
      return std::pair{clampCell((w - 1 - x + 0.5) * geometry_.height / w, geometry_.height),
                       clampCell((h - 1 - y + 0.5) * geometry_.layers / h, geometry_.layers)};
    });
    cairo_surface_mark_dirty(canvas.surface);
    cairo_t* cr = canvas.cr;
    text(cr, margin, 26, title, 16);
    text(cr, margin, 48,
         std::string(byModulus ? "coloured by Young's modulus (log scale)" : "coloured by material") +
             "; shaded by depth (brighter = nearer); to scale, " + format("%.1f", 10.0 * scale) + " px per cm",
         12);
    text(cr, topX, topY - 6, "top (looking down: x right, y up)", 12);
    text(cr, topX, frontY - 6, "front (looking along +y: x right, z up)", 12);
    text(cr, sideX, frontY - 6, "right side (looking along -x: y right, z up)", 12);
    // A 10 mm scale bar (or 1 mm for small parts) under the front view.
    const double barMm = xMm >= 20 ? 10.0 : 1.0;
    const double barY = frontY + frontH + 20;
    cairo_set_source_rgb(cr, 0.1, 0.1, 0.12);
    cairo_rectangle(cr, topX, barY, barMm * scale, 4);
    cairo_fill(cr);
    text(cr, topX + barMm * scale + 8, barY + 7, format("%.0f mm", barMm), 12);
    // Legend to the right of the top view.
    double ly = topY + 8;
    const double lx = sideX;
    if (byModulus) {
      for (int i = 0; i < 120; ++i) {
        std::uint8_t rgb[3];
        modulusColour(i / 119.0, rgb);
        cairo_set_source_rgb(cr, rgb[0] / 255.0, rgb[1] / 255.0, rgb[2] / 255.0);
        cairo_rectangle(cr, lx + i * 2, ly, 2, 14);
        cairo_fill(cr);
      }
      text(cr, lx, ly + 30, format("%.3g MPa", eMin), 12);
      text(cr, lx + 200, ly + 30, format("%.3g MPa", eMax), 12);
    } else {
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
    out.emplace_back(byModulus ? "previews/projections-modulus.png" : "previews/projections-material.png",
                     surfaceToPng(canvas.surface));
  }

  // Contact sheet: evenly spaced layers, four per row, as seen from above.
  const int columns = std::min<int>(4, static_cast<int>(contactLayers_.size()));
  const int rows = (static_cast<int>(contactLayers_.size()) + columns - 1) / columns;
  const int cellW = tileWidth_ + 24, cellH = tileHeight_ + 40;
  const int sheetW = std::max(margin * 2 + columns * cellW, 560), sheetH = 64 + rows * cellH + margin;
  Canvas sheet(sheetW, sheetH);
  for (std::size_t s = 0; s < contactLayers_.size(); ++s) {
    const int ox = margin + static_cast<int>(s % columns) * cellW, oy = 64 + static_cast<int>(s / columns) * cellH + 20;
    const std::vector<std::uint8_t>& tile = tiles_[s];
    for (int y = 0; y < tileHeight_; ++y)
      for (int x = 0; x < tileWidth_; ++x) {
        const std::uint8_t code = tile.empty() ? 0 : tile[static_cast<std::size_t>(y) * tileWidth_ + x];
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
  for (std::size_t s = 0; s < contactLayers_.size(); ++s) {
    const int ox = margin + static_cast<int>(s % columns) * cellW, oy = 64 + static_cast<int>(s / columns) * cellH + 14;
    text(sheet.cr, ox, oy, "layer " + std::to_string(contactLayers_[s]) + "  z " +
                               format("%.2f mm", contactLayers_[s] * profile_.voxelSizeMm[2]), 12);
  }
  out.emplace_back("previews/contact-sheet.png", surfaceToPng(sheet.surface));
  return out;
}

}  // namespace rodfab::printer_profiles
