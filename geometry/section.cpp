#include "geometry/section.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace rodfab::geometry {

std::string_view toString(SectionShape shape) {
  switch (shape) {
    case SectionShape::Circle: return "circle";
    case SectionShape::Ellipse: return "ellipse";
    case SectionShape::Rectangle: return "rectangle";
  }
  return "unknown";
}

double Section::normalizedRadius(double x1, double x2) const {
  const double a = x1 / (0.5 * width), b = x2 / (0.5 * height);
  if (shape == SectionShape::Rectangle) return std::max(std::abs(a), std::abs(b));
  return std::sqrt(a * a + b * b);
}

double Section::boundingRadius() const {
  if (shape == SectionShape::Rectangle) return 0.5 * std::hypot(width, height);
  return 0.5 * std::max(width, height);
}

double Section::area() const {
  if (shape == SectionShape::Rectangle) return width * height;
  return std::numbers::pi * 0.25 * width * height;
}

double Section::perimeter() const {
  if (shape == SectionShape::Rectangle) return 2.0 * (width + height);
  const double a = 0.5 * width, b = 0.5 * height, h = (a - b) * (a - b) / ((a + b) * (a + b));
  return std::numbers::pi * (a + b) * (1.0 + 3.0 * h / (10.0 + std::sqrt(4.0 - 3.0 * h)));
}

}  // namespace rodfab::geometry
