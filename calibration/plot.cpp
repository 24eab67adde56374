#include "calibration/plot.hpp"

#include "common/output_file.hpp"
#include "common/plot_canvas.hpp"
#include "common/png_tag.hpp"


#include <cstdint>
#include <string_view>

#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <stdexcept>
#include <string>

namespace rodfab::calibration {

namespace {

constexpr std::string_view kSoftware = "rodfab calibrate";  // the tag that marks the plots rodfab may replace

constexpr int kWidth = 960, kHeight = 640;
constexpr double kLeft = 96, kRight = 32, kTop = 56, kBottom = 76;

struct Rgb {
  double r, g, b;
};
constexpr Rgb kInk{0.1, 0.1, 0.1}, kGrid{0.86, 0.86, 0.86}, kCurve{0.12, 0.35, 0.75}, kFloor{0.80, 0.12, 0.12},
    kFloorShade{0.98, 0.88, 0.88};

std::string format(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

// Maps Vero fraction and log10 modulus to the plot area.
struct Axes {
  double logMin, logMax;  // whole decades
  double x(double fraction) const { return kLeft + fraction * (kWidth - kLeft - kRight); }
  double y(double modulusMpa) const {
    return kHeight - kBottom - (std::log10(modulusMpa) - logMin) / (logMax - logMin) * (kHeight - kTop - kBottom);
  }
};

void color(cairo_t* cr, Rgb c) { cairo_set_source_rgb(cr, c.r, c.g, c.b); }

enum class Align { Left, Center, Right };

void text(cairo_t* cr, double x, double y, const std::string& s, Align align = Align::Left, double size = 14) {
  cairo_set_font_size(cr, size);
  cairo_text_extents_t e;
  cairo_text_extents(cr, s.c_str(), &e);
  const double dx = align == Align::Left ? 0 : align == Align::Center ? e.x_advance / 2 : e.x_advance;
  cairo_move_to(cr, x - dx, y);
  cairo_show_text(cr, s.c_str());
}

std::string decadeLabel(int exponent) {
  return exponent >= 0 ? format("%.0f", std::pow(10.0, exponent)) : format("%g", std::pow(10.0, exponent));
}

void drawAxes(cairo_t* cr, const Axes& a) {
  const double x0 = a.x(0), x1 = a.x(1);
  const double yBottom = kHeight - kBottom, yTop = kTop;
  cairo_set_line_width(cr, 1);
  for (int k = 0; k <= 10; ++k) {  // fraction grid every 10 %, labels every 20 %
    const double x = a.x(k / 10.0);
    color(cr, kGrid);
    cairo_move_to(cr, x, yBottom);
    cairo_line_to(cr, x, yTop);
    cairo_stroke(cr);
    color(cr, kInk);
    cairo_move_to(cr, x, yBottom);
    cairo_line_to(cr, x, yBottom + (k % 2 ? 4 : 7));
    cairo_stroke(cr);
    if (k % 2 == 0) text(cr, x, yBottom + 24, format("%.0f %%", k * 10.0), Align::Center);
  }
  for (int d = static_cast<int>(a.logMin); d <= static_cast<int>(a.logMax); ++d) {
    for (int m = 1; m <= 9; ++m) {
      const double value = m * std::pow(10.0, d);
      if (std::log10(value) > a.logMax + 1e-9) break;
      const double y = a.y(value);
      color(cr, m == 1 ? Rgb{0.75, 0.75, 0.75} : kGrid);
      cairo_move_to(cr, x0, y);
      cairo_line_to(cr, x1, y);
      cairo_stroke(cr);
      color(cr, kInk);
      cairo_move_to(cr, x0 - (m == 1 ? 7 : 4), y);
      cairo_line_to(cr, x0, y);
      cairo_stroke(cr);
      if (m == 1) text(cr, x0 - 11, y + 5, decadeLabel(d), Align::Right);
    }
  }
  color(cr, kInk);
  cairo_set_line_width(cr, 1.5);
  cairo_rectangle(cr, x0, yTop, x1 - x0, yBottom - yTop);
  cairo_stroke(cr);
  text(cr, (x0 + x1) / 2, kHeight - 22, "Vero fraction (VeroWhitePlus in TangoBlackPlus)", Align::Center, 15);
  cairo_save(cr);
  cairo_translate(cr, 28, (yTop + yBottom) / 2);
  cairo_rotate(cr, -M_PI / 2);
  text(cr, 0, 0, "modulus E (MPa, log scale)", Align::Center, 15);
  cairo_restore(cr);
}

void circle(cairo_t* cr, double x, double y, double radius) {
  cairo_new_sub_path(cr);
  cairo_arc(cr, x, y, radius, 0, 2 * M_PI);
}

std::string fitLabel(const Calibration& c) {
  const ModelParameters& p = c.parameters();
  switch (p.model) {
    case Model::Pchip: return "fit: pchip in ln E through the per-fraction means";
    case Model::Lichtenecker: return "fit: Lichtenecker, exponent a = " + format("%.4f", p.exponent);
    case Model::LogPower: return "fit: log-power law, exponent n = " + format("%.4f", p.exponent);
  }
  return {};
}

using Groups = std::map<double, std::pair<double, int>>;  // fraction -> (sum of ln E, count)
constexpr double kDash[] = {7, 5};

// The band below the floor shaded like the paper's red box (requests there are raised to the floor),
// the axes over it, and the floor: its modulus across the plot, its fraction down to the axis.
void drawFloor(cairo_t* cr, const Axes& a, const Calibration& c, double yFloor) {
  color(cr, kFloorShade);
  cairo_rectangle(cr, a.x(0), yFloor, a.x(1) - a.x(0), kHeight - kBottom - yFloor);
  cairo_fill(cr);
  drawAxes(cr, a);
  color(cr, kFloor);
  cairo_set_line_width(cr, 1.5);
  cairo_set_dash(cr, kDash, 2, 0);
  cairo_move_to(cr, a.x(0), yFloor);
  cairo_line_to(cr, a.x(1), yFloor);
  cairo_move_to(cr, a.x(c.floorFraction()), yFloor);
  cairo_line_to(cr, a.x(c.floorFraction()), kHeight - kBottom);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
}

void drawCurve(cairo_t* cr, const Axes& a, const Calibration& c) {
  color(cr, kCurve);
  cairo_set_line_width(cr, 2.5);
  constexpr int kSamples = 500;
  for (int i = 0; i <= kSamples; ++i) {
    const double f = static_cast<double>(i) / kSamples;
    if (i == 0) cairo_move_to(cr, a.x(f), a.y(c.modulusMpa(f)));
    else cairo_line_to(cr, a.x(f), a.y(c.modulusMpa(f)));
  }
  cairo_stroke(cr);
}

// Every replicate as an open circle, and each fraction's mean (in ln E) as a bar where there are
// replicates; returns the measurements grouped by fraction.
Groups drawMeasurements(cairo_t* cr, const Axes& a, const std::vector<Measurement>& measurements) {
  Groups groups;
  color(cr, kInk);
  cairo_set_line_width(cr, 1.6);
  for (const Measurement& m : measurements) {
    circle(cr, a.x(m.veroFraction), a.y(m.modulusMpa), 5.5);
    auto& g = groups[m.veroFraction];
    g.first += std::log(m.modulusMpa);
    g.second += 1;
  }
  cairo_stroke(cr);
  for (const auto& [f, g] : groups) {
    if (g.second < 2) continue;
    const double y = a.y(std::exp(g.first / g.second));
    cairo_move_to(cr, a.x(f) - 10, y);
    cairo_line_to(cr, a.x(f) + 10, y);
  }
  cairo_stroke(cr);
  return groups;
}

// The legend, top left inside the plot where the curve is low: the fit, the measurements, the floor
// and the band below it.
void drawLegend(cairo_t* cr, const Axes& a, const Calibration& c, const Groups& groups, const std::string& floorText) {
  const std::size_t measurements = c.record().measurements.size();
  const double lx = a.x(0) + 16, ly = kTop + 16;
  color(cr, Rgb{1, 1, 1});
  cairo_rectangle(cr, lx - 8, ly - 8, 410, 104);
  cairo_fill_preserve(cr);
  color(cr, kInk);
  cairo_set_line_width(cr, 1);
  cairo_stroke(cr);
  const double row = 24;
  color(cr, kCurve);
  cairo_set_line_width(cr, 2.5);
  cairo_move_to(cr, lx, ly + 8);
  cairo_line_to(cr, lx + 30, ly + 8);
  cairo_stroke(cr);
  color(cr, kInk);
  text(cr, lx + 40, ly + 13, fitLabel(c), Align::Left, 13);
  cairo_set_line_width(cr, 1.6);
  circle(cr, lx + 15, ly + 8 + row, 5);
  cairo_stroke(cr);
  const std::size_t replicates = measurements - groups.size();
  text(cr, lx + 40, ly + 13 + row,
       std::to_string(measurements) + " measurements at " + std::to_string(groups.size()) + " fractions" +
           (replicates ? " (bars: means in ln E)" : ""),
       Align::Left, 13);
  color(cr, kFloor);
  cairo_set_line_width(cr, 1.5);
  cairo_set_dash(cr, kDash, 2, 0);
  cairo_move_to(cr, lx, ly + 8 + 2 * row);
  cairo_line_to(cr, lx + 30, ly + 8 + 2 * row);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
  color(cr, kInk);
  text(cr, lx + 40, ly + 13 + 2 * row, "floor " + floorText, Align::Left, 13);
  color(cr, kFloorShade);
  cairo_rectangle(cr, lx, ly + 2 + 3 * row, 30, 12);
  cairo_fill(cr);
  color(cr, kInk);
  text(cr, lx + 40, ly + 13 + 3 * row, "below the floor: raised to the floor's fraction", Align::Left, 13);
}

std::string plotTitle(const FitRecord& r) {
  std::string title = "Modulus vs Vero fraction";
  if (r.temperatureC) title += format(" at %.0f \u00B0C", *r.temperatureC);
  if (!r.dither.empty()) title += ", " + r.dither + " dither";
  if (!r.dataFile.empty()) title += ", " + std::filesystem::path(r.dataFile).filename().string();
  return title;
}

}  // namespace

std::string renderFitPlot(const Calibration& c) {
  const auto& measurements = c.record().measurements;
  double lo = std::min({c.minModulusMpa(), c.floorMpa()}), hi = c.maxModulusMpa();
  for (const Measurement& m : measurements) lo = std::min(lo, m.modulusMpa), hi = std::max(hi, m.modulusMpa);
  const Axes a{std::floor(std::log10(lo)), std::max(std::ceil(std::log10(hi)), std::floor(std::log10(lo)) + 1)};

  const common::PlotCanvas canvas(kWidth, kHeight);
  cairo_t* cr = canvas.context();

  const double yFloor = c.floorMpa() > 0 ? a.y(c.floorMpa()) : kHeight - kBottom;
  drawFloor(cr, a, c, yFloor);
  drawCurve(cr, a, c);
  // The floor point under the measurements, so a coupon measured right at the floor stays visible.
  color(cr, kFloor);
  circle(cr, a.x(c.floorFraction()), yFloor, 4);
  cairo_fill(cr);
  const Groups groups = drawMeasurements(cr, a, measurements);
  const std::string floorText = format("%g MPa", c.floorMpa()) + " at " + format("%.1f %% Vero", 100 * c.floorFraction());
  text(cr, a.x(c.floorFraction()) + 10, yFloor + 20, floorText, Align::Left, 13);
  drawLegend(cr, a, c, groups, floorText);
  text(cr, kLeft, 34, plotTitle(c.record()), Align::Left, 17);

  return canvas.png(kSoftware);
}

void writeFitPlot(const Calibration& c, const std::filesystem::path& png) {
  std::string bytes;
  try {
    bytes = renderFitPlot(c);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(png.string() + ": " + e.what());
  }
  common::writeFileAtomically(png, bytes);
}

bool isFitPlot(const std::filesystem::path& png) {
  return common::hasSoftwareTag(png, kSoftware);
}

}  // namespace rodfab::calibration
