// Stiffness constants of a rod's cross-section: area, second moments about the frame directions,
// torsion constant and shear correction factor. They scale with E(s) into C and D of the Cosserat
// constitutive law.
#pragma once

#include "geometry/section.hpp"

#include <optional>

namespace rodfab::mechanics {

struct SectionProperties {
  double area = 0.0;             // A, mm^2
  double inertia1 = 0.0;         // I1 = integral of x2^2 dA: bending about d1, mm^4
  double inertia2 = 0.0;         // I2 = integral of x1^2 dA: bending about d2, mm^4
  double torsionConstant = 0.0;  // J (Saint-Venant), mm^4
  double shearFactor = 0.0;      // k in the shear stiffness k G A
};

// Exact A, I1, I2 for circles, ellipses and rectangles; J exact for circles and ellipses and from
// Saint-Venant's series for rectangles; k from Cowper (1966) for the shape and Poisson ratio `nu`.
SectionProperties sectionProperties(const geometry::Section& section, double nu);

}  // namespace rodfab::mechanics
