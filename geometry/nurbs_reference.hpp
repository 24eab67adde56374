// Internal to geometry/ (and its tests): the general NURBS basis algorithm (The NURBS Book A2.3) for
// every degree up to kMaxDegree, the reference the fixed-degree paths of basisFunctionDerivatives
// (degrees 1..3, orders 0..2) equal bit for bit. Callers use basisFunctionDerivatives (nurbs.hpp).
#pragma once

#include "geometry/nurbs.hpp"

#include <vector>

namespace rodfab::geometry {

// As basisFunctionDerivatives, always by the general loops. Same preconditions; thread-safe; throws nothing.
void basisFunctionDerivativesAnyDegree(const std::vector<double>& knots, int degree, int span, double u, int order,
                                       BasisDerivatives& ders);

}  // namespace rodfab::geometry
