// The white canvas rodfab's plots and renders are drawn on (cairo), and its PNG file.
#pragma once

#include "common/memory_budget.hpp"

#include <string>
#include <string_view>

typedef struct _cairo cairo_t;                  // as <cairo.h> declares them
typedef struct _cairo_surface cairo_surface_t;

namespace rodfab::common {

// A width x height RGB image, painted white, with the "sans-serif" face selected. Throws
// std::runtime_error("cairo: ...") when cairo cannot make it (sizes beyond its limits, no memory).
// While it lives the memory budget's data limit is lifted (DataLimitLifted): what is drawn on it must
// be bounded by its caller.
// Not thread-safe: one thread draws on one canvas.
class PlotCanvas {
public:
  PlotCanvas(int width, int height);
  ~PlotCanvas();
  PlotCanvas(const PlotCanvas&) = delete;
  PlotCanvas& operator=(const PlotCanvas&) = delete;

  cairo_t* context() const { return context_; }
  // The PNG file's bytes, marked for `software` by withSoftwareTag (common/png_tag.hpp), or unmarked
  // when `software` is empty. Throws std::runtime_error("cairo PNG encoding failed: ...").
  std::string png(std::string_view software) const;

private:
  DataLimitLifted lifted_;  // first made, last gone: cairo cannot survive a failed allocation
  cairo_surface_t* surface_ = nullptr;
  cairo_t* context_ = nullptr;
};

}  // namespace rodfab::common
