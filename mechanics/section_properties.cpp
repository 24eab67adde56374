#include "mechanics/section_properties.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace rodfab::mechanics {

namespace {

// Saint-Venant torsion constant of a rectangle with sides a >= b: J = a b^3 (1/3 - 64 b / (pi^5 a)
// sum over odd n of tanh(n pi a / (2 b)) / n^5). The series converges like n^-5; 50 terms is
// far below double precision.
double rectangleTorsionConstant(double width, double height) {
  const double a = std::max(width, height), b = std::min(width, height);
  double sum = 0.0;
  for (int n = 1; n < 100; n += 2) sum += std::tanh(n * std::numbers::pi * a / (2.0 * b)) / std::pow(n, 5);
  return a * b * b * b * (1.0 / 3.0 - 64.0 * b / (std::pow(std::numbers::pi, 5) * a) * sum);
}

}  // namespace

SectionProperties sectionProperties(const geometry::Section& section, double nu) {
  using geometry::SectionShape;
  const double pi = std::numbers::pi;
  SectionProperties p;
  const double a = 0.5 * section.width, b = 0.5 * section.height;  // semi-axes along d1, d2
  switch (section.shape) {
    case SectionShape::Circle:
    case SectionShape::Ellipse:
      p.area = pi * a * b;
      p.inertia1 = pi * a * b * b * b / 4.0;
      p.inertia2 = pi * a * a * a * b / 4.0;
      p.torsionConstant = pi * a * a * a * b * b * b / (a * a + b * b);
      p.shearFactor = 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu);
      break;
    case SectionShape::Rectangle:
      p.area = section.width * section.height;
      p.inertia1 = section.width * std::pow(section.height, 3) / 12.0;
      p.inertia2 = section.height * std::pow(section.width, 3) / 12.0;
      p.torsionConstant = rectangleTorsionConstant(section.width, section.height);
      p.shearFactor = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu);
      break;
  }
  return p;
}

}  // namespace rodfab::mechanics
