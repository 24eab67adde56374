// Rod cross-sections and the point-in-section test in frame coordinates.
#pragma once

#include <string_view>

namespace rodfab::geometry {

enum class SectionShape { Circle, Ellipse, Rectangle };

std::string_view toString(SectionShape shape);

// A cross-section centred on the centerline. `width` is measured along the frame's d1 and `height`
// along d2; a circle has width == height == diameter.
struct Section {
  SectionShape shape = SectionShape::Circle;
  double width = 1.0;
  double height = 1.0;

  static Section circle(double diameter) { return {SectionShape::Circle, diameter, diameter}; }
  static Section ellipse(double width, double height) { return {SectionShape::Ellipse, width, height}; }
  static Section rectangle(double width, double height) { return {SectionShape::Rectangle, width, height}; }

  // Gauge of (x1, x2) (coordinates along d1, d2): 0 on the centerline, 1 on the boundary, > 1 outside.
  // Comparable across sections, so it ranks how deep a point lies inside overlapping rods.
  double normalizedRadius(double x1, double x2) const;
  bool contains(double x1, double x2) const { return normalizedRadius(x1, x2) <= 1.0; }

  // Largest distance from the centerline to the boundary (half the diagonal for rectangles).
  double boundingRadius() const;
  // Radius of a round end cap: half the smaller section dimension.
  double capRadius() const { return 0.5 * (width < height ? width : height); }
  double area() const;
  // Boundary length in mm (Ramanujan's second approximation for ellipses: relative error below 5e-4 at
  // any aspect ratio).
  double perimeter() const;
  bool isRotationallySymmetric() const { return shape == SectionShape::Circle; }
};

}  // namespace rodfab::geometry
