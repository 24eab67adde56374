#include "common/plot_canvas.hpp"

#include "common/png_tag.hpp"

#include <cairo.h>

#include <stdexcept>

namespace rodfab::common {

namespace {

cairo_status_t appendToString(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

}  // namespace

PlotCanvas::PlotCanvas(int width, int height)
    : surface_(cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height)), context_(cairo_create(surface_)) {
  if (cairo_status(context_) != CAIRO_STATUS_SUCCESS) {
    const std::string reason = cairo_status_to_string(cairo_status(context_));
    cairo_destroy(context_);
    cairo_surface_destroy(surface_);
    throw std::runtime_error("cairo: " + reason);
  }
  cairo_select_font_face(context_, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_source_rgb(context_, 1, 1, 1);
  cairo_paint(context_);
}

PlotCanvas::~PlotCanvas() {
  cairo_destroy(context_);
  cairo_surface_destroy(surface_);
}

std::string PlotCanvas::png(std::string_view software) const {
  cairo_surface_flush(surface_);
  std::string bytes;
  const cairo_status_t status = cairo_surface_write_to_png_stream(surface_, appendToString, &bytes);
  if (status != CAIRO_STATUS_SUCCESS) throw std::runtime_error(std::string("cairo PNG encoding failed: ") + cairo_status_to_string(status));
  return software.empty() ? bytes : withSoftwareTag(bytes, software);
}

}  // namespace rodfab::common
