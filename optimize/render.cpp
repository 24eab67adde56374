// The shape render of `rodfab optimize --render`: per load case, the target, the deformed shape
// with the starting modulus and the one with the optimized modulus side by side, each in three
// orthographic views, rods coloured by E with a colour bar. Drawn with cairo like the plots.
#include "optimize/optimize.hpp"

#include "common/interrupt.hpp"
#include "common/output_file.hpp"
#include "common/plot_canvas.hpp"

#include <cairo.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string_view>

namespace rodfab::optimize {

namespace {

constexpr std::string_view kSoftware = "rodfab optimize";  // as the convergence plot: files rodfab optimize may replace
constexpr int kPanel = 300, kMargin = 20, kLabel = 24, kTitle = 44, kCaseHeader = 30, kBar = 110;
constexpr int kColumns = 3, kViews = 3;
constexpr std::size_t kMaxCases = 4;  // more cases: the first ones, the title says how many
constexpr std::array<const char*, kColumns> kColumnNames = {"target", "start", "optimized"};
constexpr std::array<const char*, kViews> kViewNames = {"front (x, z)", "side (y, z)", "top (x, y)"};

// Orthographic views: the two drawn coordinates and the depth (towards the viewer) per view.
struct View {
  int h, v, depth;
  double depthSign;
};
constexpr std::array<View, kViews> kViewAxes = {View{0, 2, 1, -1.0}, View{1, 2, 0, 1.0}, View{0, 1, 2, 1.0}};

// Viridis at 9 stops (matplotlib's), interpolated linearly: light for stiff, dark for soft.
Eigen::Vector3d colourOf(double t) {
  static const std::array<Eigen::Vector3d, 9> stops = {
      Eigen::Vector3d(0.267, 0.005, 0.329), Eigen::Vector3d(0.278, 0.175, 0.483), Eigen::Vector3d(0.231, 0.322, 0.546),
      Eigen::Vector3d(0.173, 0.449, 0.558), Eigen::Vector3d(0.128, 0.567, 0.551), Eigen::Vector3d(0.153, 0.683, 0.503),
      Eigen::Vector3d(0.361, 0.785, 0.388), Eigen::Vector3d(0.680, 0.860, 0.201), Eigen::Vector3d(0.993, 0.906, 0.144)};
  const double x = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * (stops.size() - 1);
  const std::size_t i = std::min(static_cast<std::size_t>(x), stops.size() - 2);
  return stops[i] + (x - i) * (stops[i + 1] - stops[i]);
}

void text(cairo_t* cr, double x, double y, const std::string& s, double size, bool centred = false) {
  cairo_set_font_size(cr, size);
  cairo_text_extents_t e;
  cairo_text_extents(cr, s.c_str(), &e);
  cairo_move_to(cr, centred ? x - e.x_advance / 2 : x, y);
  cairo_show_text(cr, s.c_str());
}

// The box around every point of a case (all three columns), so the columns share one scale.
struct Bounds {
  Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d high = -low;
  void add(const std::vector<DrawnRod>& rods) {
    for (const DrawnRod& r : rods)
      for (const Eigen::Vector3d& p : r.points)
        if (p.allFinite()) low = low.cwiseMin(p), high = high.cwiseMax(p);
  }
};

// One panel's mapping from space to pixels: the case's bounds centred, one scale for every view.
struct Projection {
  View view;
  double scale, x0, y0;
  Eigen::Vector3d centre;
  double x(const Eigen::Vector3d& p) const { return x0 + scale * (p[view.h] - centre[view.h]); }
  double y(const Eigen::Vector3d& p) const { return y0 - scale * (p[view.v] - centre[view.v]); }
  double depth(const Eigen::Vector3d& p) const { return view.depthSign * p[view.depth]; }
};

double caseScale(const Bounds& b) {
  const Eigen::Vector3d size = (b.high - b.low).cwiseMax(1e-9);
  double scale = std::numeric_limits<double>::infinity();
  for (const View& v : kViewAxes) scale = std::min({scale, (kPanel - 24.0) / size[v.h], (kPanel - 24.0) / size[v.v]});
  return std::isfinite(scale) ? scale : 1.0;
}

struct Segment {
  double depth;
  Eigen::Vector3d a, b;
  double modulus;  // NaN: a target segment
};

// The rods' segments, far ones first (painter's order), so nearer rods cover farther ones.
std::vector<Segment> segmentsByDepth(const std::vector<DrawnRod>& rods, const Projection& p) {
  std::vector<Segment> out;
  for (const DrawnRod& r : rods)
    for (std::size_t i = 1; i < r.points.size(); ++i) {
      const double e = r.modulusMpa.size() == r.points.size() ? 0.5 * (r.modulusMpa[i - 1] + r.modulusMpa[i])
                                                               : std::numeric_limits<double>::quiet_NaN();
      out.push_back({p.depth(r.points[i - 1] + r.points[i]), r.points[i - 1], r.points[i], e});
    }
  std::stable_sort(out.begin(), out.end(), [](const Segment& a, const Segment& b) { return a.depth < b.depth; });
  return out;
}

void drawRods(cairo_t* cr, const std::vector<DrawnRod>& rods, const Projection& p, double lower, double upper, bool ghost) {
  cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
  cairo_set_line_width(cr, ghost ? 3.0 : 2.2);
  for (const Segment& s : segmentsByDepth(rods, p)) {
    if (ghost) cairo_set_source_rgb(cr, 0.82, 0.84, 0.90);
    else if (std::isnan(s.modulus)) cairo_set_source_rgb(cr, 0.20, 0.35, 0.80);
    else {
      const Eigen::Vector3d c = colourOf((s.modulus - lower) / (upper - lower));
      cairo_set_source_rgb(cr, c.x(), c.y(), c.z());
    }
    if (!s.a.allFinite() || !s.b.allFinite()) continue;
    cairo_move_to(cr, p.x(s.a), p.y(s.a));
    cairo_line_to(cr, p.x(s.b), p.y(s.b));
    cairo_stroke(cr);
  }
}

// One case: a header, then a row per view with the three columns.
void drawCase(cairo_t* cr, const ShapeColumns& c, int top, double lower, double upper) {
  Bounds b;
  for (const auto* rods : {&c.target, &c.start, &c.optimized}) b.add(*rods);
  const double scale = caseScale(b);
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
  text(cr, kMargin, top + 20, "load case \"" + c.name + "\"", 15);
  for (int v = 0; v < kViews; ++v)
    for (int col = 0; col < kColumns; ++col) {
      common::throwIfInterrupted();
      const int x = kMargin + col * kPanel, y = top + kCaseHeader + kLabel + v * (kPanel + kLabel);
      cairo_set_source_rgb(cr, 0.975, 0.975, 0.975);
      cairo_rectangle(cr, x + 2, y, kPanel - 4, kPanel - 4);
      cairo_fill(cr);
      cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
      text(cr, x + kPanel / 2.0, y - 6, std::string(kColumnNames[col]) + ", " + kViewNames[v], 13, true);
      const Projection p{kViewAxes[v], scale, x + kPanel / 2.0, y + (kPanel - 4) / 2.0, 0.5 * (b.low + b.high)};
      if (col == 0) drawRods(cr, c.target, p, lower, upper, false);
      else {
        drawRods(cr, c.target, p, lower, upper, true);  // the target underneath, pale
        drawRods(cr, col == 1 ? c.start : c.optimized, p, lower, upper, false);
      }
    }
}

void drawColourBar(cairo_t* cr, int top, double lower, double upper) {
  const int x = kMargin + kColumns * kPanel + 24, height = 2 * kPanel, width = 22;
  for (int i = 0; i < height; ++i) {
    const Eigen::Vector3d c = colourOf(1.0 - (i + 0.5) / height);
    cairo_set_source_rgb(cr, c.x(), c.y(), c.z());
    cairo_rectangle(cr, x, top + i, width, 1);
    cairo_fill(cr);
  }
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
  for (int k = 0; k <= 4; ++k) {
    char label[32];
    std::snprintf(label, sizeof label, "%.4g", lower + (upper - lower) * k / 4.0);
    text(cr, x + width + 4, top + height - k * height / 4.0 + 4, label, 12);
  }
  text(cr, x - 4, top - 10, "E (MPa)", 13);
}

}  // namespace

std::vector<DrawnRod> drawnTarget(const std::vector<mechanics::TargetRod>& target, int samplesPerRod) {
  std::vector<DrawnRod> out;
  for (const mechanics::TargetRod& t : target) {
    DrawnRod r;
    const double a = t.centerline.domainBegin(), b = t.centerline.domainEnd();
    for (int i = 0; i <= samplesPerRod; ++i) r.points.push_back(t.centerline.point(a + (b - a) * i / samplesPerRod));
    out.push_back(std::move(r));
  }
  return out;
}

std::vector<DrawnRod> drawnDeformed(const DesignProblem& problem, std::size_t c, const Eigen::VectorXd& modulus, int samplesPerRod) {
  const mechanics::Design design = problem.designWith(modulus);
  const mechanics::StaticProblem& sp = problem.caseProblem(c);
  std::vector<DrawnRod> out;
  for (std::size_t rod = 0; rod < design.rods.size(); ++rod) {
    const geometry::Rod& r = design.rods[rod];
    const double a = r.centerline().domainBegin(), b = r.centerline().domainEnd();
    DrawnRod d;
    for (int i = 0; i <= samplesPerRod; ++i) {
      const double u = a + (b - a) * i / samplesPerRod;
      d.points.push_back(sp.position(problem.state(c), rod, u));
      d.modulusMpa.push_back(r.modulus().value(u));
    }
    out.push_back(std::move(d));
  }
  return out;
}

void writeShapeRender(const std::vector<ShapeColumns>& cases, double lowerMpa, double upperMpa, const std::filesystem::path& png,
                      const std::string& title) {
  if (cases.empty()) throw std::invalid_argument("writeShapeRender: no load case to draw");
  if (!(upperMpa > lowerMpa)) throw std::invalid_argument("writeShapeRender: lower < upper expected");
  const std::size_t drawn = std::min(cases.size(), kMaxCases);
  const int caseHeight = kCaseHeader + kViews * (kPanel + kLabel);
  const int width = 2 * kMargin + kColumns * kPanel + kBar, height = kTitle + static_cast<int>(drawn) * caseHeight + kMargin;
  const common::PlotCanvas canvas(width, height);
  cairo_t* cr = canvas.context();
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
  std::string heading = title.empty() ? "target, start and optimized shapes" : title;
  if (drawn < cases.size()) heading += " (the first " + std::to_string(drawn) + " of " + std::to_string(cases.size()) + " load cases)";
  text(cr, kMargin, 30, heading, 17);
  for (std::size_t c = 0; c < drawn; ++c) drawCase(cr, cases[c], kTitle + static_cast<int>(c) * caseHeight, lowerMpa, upperMpa);
  drawColourBar(cr, kTitle + kCaseHeader + kLabel, lowerMpa, upperMpa);
  const std::string bytes = canvas.png(kSoftware);
  common::throwIfInterrupted();
  common::writeFileAtomically(png, bytes);
}

std::vector<ShapeColumns> startingShapes(const mechanics::Design& design, const DesignProblem& problem, const Eigen::VectorXd& start) {
  std::vector<ShapeColumns> shapes;
  for (std::size_t i = 0; i < problem.caseCount(); ++i) {
    const mechanics::LoadCase& lc = design.mechanics.loadCases.at(i);
    if (!lc.target.empty()) shapes.push_back({lc.name, drawnTarget(lc.target), drawnDeformed(problem, i, start), {}});
  }
  return shapes;
}

void addOptimizedShapes(const mechanics::Design& design, const DesignProblem& problem, const Eigen::VectorXd& modulus,
                        std::vector<ShapeColumns>& shapes) {
  std::size_t k = 0;
  for (std::size_t i = 0; i < problem.caseCount(); ++i)
    if (!design.mechanics.loadCases.at(i).target.empty()) shapes.at(k++).optimized = drawnDeformed(problem, i, modulus);
}

}  // namespace rodfab::optimize
