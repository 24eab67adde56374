// The convergence plot of `rodfab optimize --plot`: g / g0 against iteration on a log axis, PNG
// drawn with cairo like the calibration plot.
#include "optimize/optimize.hpp"

#include "common/output_file.hpp"
#include "common/plot_canvas.hpp"
#include "common/png_tag.hpp"

#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string_view>

namespace rodfab::optimize {

namespace {

constexpr std::string_view kSoftware = "rodfab optimize";  // the tag that marks the plots rodfab may replace
constexpr int kWidth = 960, kHeight = 640;
constexpr double kLeft = 96, kRight = 32, kTop = 56, kBottom = 76;

void text(cairo_t* cr, double x, double y, const std::string& s, double size = 14, bool right = false) {
  cairo_set_font_size(cr, size);
  cairo_text_extents_t e;
  cairo_text_extents(cr, s.c_str(), &e);
  cairo_move_to(cr, right ? x - e.x_advance : x - (size < 14 ? e.x_advance / 2 : 0), y);
  cairo_show_text(cr, s.c_str());
}

// Plot coordinates: iteration on x, log10(g / g0) on y between whole decades.
struct Axes {
  int last;
  int decadeLow;  // <= 0
  double x(double i) const { return kLeft + i / std::max(1, last) * (kWidth - kLeft - kRight); }
  double y(double relative) const {
    const double l = std::clamp(std::log10(std::max(relative, 1e-300)), double(decadeLow), 0.0);
    return kTop + l / decadeLow * (kHeight - kTop - kBottom);
  }
};

void drawAxes(cairo_t* cr, const Axes& a) {
  cairo_set_line_width(cr, 1.0);
  for (int d = 0; d >= a.decadeLow; --d) {
    cairo_set_source_rgb(cr, 0.86, 0.86, 0.86);
    cairo_move_to(cr, kLeft, a.y(std::pow(10.0, d)));
    cairo_line_to(cr, kWidth - kRight, a.y(std::pow(10.0, d)));
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
    text(cr, kLeft - 8, a.y(std::pow(10.0, d)) + 5, d == 0 ? "1" : "1e" + std::to_string(d), 13, true);
  }
  const int step = std::max(1, static_cast<int>(std::ceil(a.last / 10.0)));
  for (int i = 0; i <= a.last; i += step) text(cr, a.x(i), kHeight - kBottom + 20, std::to_string(i), 13);
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
  cairo_rectangle(cr, kLeft, kTop, kWidth - kLeft - kRight, kHeight - kTop - kBottom);
  cairo_stroke(cr);
  text(cr, kWidth / 2.0 - 30, kHeight - 24, "iteration", 15);
  text(cr, 12, kTop - 12, "g / g0", 15);
}

}  // namespace

void writeHistoryPlot(const std::vector<Iteration>& history, const std::filesystem::path& png, const std::string& title) {
  if (history.empty()) throw std::invalid_argument("writeHistoryPlot: an empty history");
  double lowest = 1.0;
  for (const Iteration& it : history) lowest = std::min(lowest, std::max(it.relative, 1e-300));
  const Axes a{history.back().index, std::min(-1, static_cast<int>(std::floor(std::log10(lowest))))};
  const common::PlotCanvas canvas(kWidth, kHeight);
  cairo_t* cr = canvas.context();
  drawAxes(cr, a);
  cairo_set_source_rgb(cr, 0.12, 0.35, 0.75);
  cairo_set_line_width(cr, 2.5);
  cairo_new_path(cr);  // no current point left by the labels: the curve starts at its first point
  for (const Iteration& it : history) cairo_line_to(cr, a.x(it.index), a.y(it.relative));
  cairo_stroke(cr);
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
  char final[96];
  std::snprintf(final, sizeof final, "g/g0 = %.3g after %d iterations", history.back().relative, history.back().index);
  text(cr, kLeft, 34, title.empty() ? final : title + ": " + final, 17);
  common::writeFileAtomically(png, canvas.png(kSoftware));
}

bool isHistoryPlot(const std::filesystem::path& png) { return common::hasSoftwareTag(png, kSoftware); }

}  // namespace rodfab::optimize
