// Choosing each rod's solver basis (solver_basis.cpp), for DiscreteStructure::buildRod: the degree
// and span count, the solver's curve, its collocation points and the interior sites' control
// points. Internal to mechanics/.
#pragma once

#include "mechanics/discrete_structure.hpp"

#include <optional>
#include <string>
#include <vector>

namespace rodfab::mechanics::detail {

// The solver's basis for one rod: how many spans, on which curve.
struct RodBasisChoice {
  bool rebuild = false;
  int degree = 0;
  int spans = 0;   // rebuilt: spans; design basis: solver spans per design span
};

// The degree and spans for design rod `index` (at JSON path `path`): given per rod, for every rod,
// or automatic for the discretization's tolerance; fails on centerlines the collocation cannot
// resolve and on span counts out of range.
RodBasisChoice chooseBasis(const DiscreteStructure& s, const geometry::Rod& rod, std::size_t index,
                           const Discretization& d, const std::string& path);

// The solver's curve: the design's refined by knot insertion, or (rebuild) a degree-p B-spline
// with placeholder control points that interpolateReference replaces.
geometry::NurbsCurve solverCurve(const geometry::Rod& rod, const RodBasisChoice& choice, const std::vector<double>& sites);

// Greville abscissae, with the ends exactly at the domain's ends.
std::vector<double> grevilleAbscissae(const geometry::NurbsCurve& curve);

// The control point of each interior site: the one whose Greville abscissa is the p-fold knot
// there (knots[k + 1 .. k + p]); its tau is set to that knot exactly, and so is the site's
// parameter (a kink merged with it may have moved it by rounding).
std::vector<int> sitePoints(const geometry::NurbsCurve& curve, std::vector<double>& sites, std::vector<double>& tau);

// A kink of E(s) that is also a collocation point (not a site's: the node rows there do not use
// E'), where the solver needs E'(s) (n' contains it); none if there is no such kink.
std::optional<double> kinkAtCollocationPoint(const geometry::BSplineField& e, const std::vector<double>& tau,
                                             const std::vector<int>& sitePoints);

}  // namespace rodfab::mechanics::detail
