// Each rod's solver basis: its degree and span count (automatic from slenderness, drawn turning
// and the modulus' grading), its knots and curve, the collocation points and the interior sites'
// control points; and the rational basis evaluated on it.
#include "mechanics/solver_basis.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace rodfab::mechanics::detail {

using geometry::Vec3;

namespace {

// The (rational) basis on knot span `span` at u, which may be the span's end.
Basis basisInSpan(const geometry::NurbsCurve& curve, int span, double u) {
  const int p = curve.degree();
  geometry::BasisDerivatives ders;
  geometry::basisFunctionDerivatives(curve.knots(), p, span, u, 2, ders);
  Basis b;
  b.first = span - p;
  b.count = p + 1;
  if (!curve.isRational()) {
    for (int i = 0; i <= p; ++i) b.value[i] = ders[0][i], b.d1[i] = ders[1][i], b.d2[i] = ders[2][i];
    return b;
  }
  // R_i = N_i w_i / W and its derivatives by the quotient rule.
  double W = 0, dW = 0, ddW = 0;
  for (int i = 0; i <= p; ++i) {
    const double w = curve.weights()[b.first + i];
    W += ders[0][i] * w, dW += ders[1][i] * w, ddW += ders[2][i] * w;
  }
  for (int i = 0; i <= p; ++i) {
    const double w = curve.weights()[b.first + i];
    b.value[i] = ders[0][i] * w / W;
    b.d1[i] = (ders[1][i] * w - b.value[i] * dW) / W;
    b.d2[i] = (ders[2][i] * w - 2.0 * b.d1[i] * dW - b.value[i] * ddW) / W;
  }
  return b;
}

}  // namespace

Basis rationalBasis(const geometry::NurbsCurve& curve, double u) {
  return basisInSpan(curve, geometry::findKnotSpan(curve.knots(), curve.degree(), static_cast<int>(curve.points().size()), u), u);
}

Basis rationalBasisBelow(const geometry::NurbsCurve& curve, double u) {
  if (u <= curve.domainBegin()) return rationalBasis(curve, u);
  // Largest i in [degree, n) with knots[i] < u: the span whose closure ends at (or contains) u.
  const auto& k = curve.knots();
  const auto first = k.begin() + curve.degree();
  const auto last = k.begin() + static_cast<std::ptrdiff_t>(curve.points().size());
  return basisInSpan(curve, static_cast<int>(std::lower_bound(first, last, u) - k.begin()) - 1, u);
}

namespace {

// Unit tangent of a curve at u approached from the left (side < 0) or the right.
Vec3 sideTangent(const geometry::NurbsCurve& c, double u, int side) {
  const double h = 1e-9 * (c.domainEnd() - c.domainBegin());
  const double at = std::clamp(u + (side < 0 ? -h : h), c.domainBegin(), c.domainEnd());
  Vec3 d[2];
  c.derivatives(at, 1, d);
  return d[1].normalized();
}

// The design's centerline must have a clamped knot vector, and the solver's degree p must allow
// second derivatives. A knot repeated `degree` times or more makes the curve only C0 there: on the
// design's own basis that is refused; a rebuilt rod (`rebuild`) interpolates the curve anyway and
// only a real corner (the tangent turning there) is refused. At an interior site (`sites`) the
// solver's basis is C0 anyway: a kink there is accepted as long as the frame need not turn with it
// (a deformed design's T-joint has one, its orientation given).
void checkCenterline(const DiscreteStructure& s, const geometry::Rod& rod, int p, bool rebuild, const std::string& path,
                     const std::vector<double>& sites) {
  const geometry::NurbsCurve& c0 = rod.centerline();
  if (p > geometry::kMaxDegree) s.fail("", "degree " + std::to_string(p) + " is above the supported " + std::to_string(geometry::kMaxDegree));
  if (p < 2)
    s.fail(path + ".centerline.degree", "the rod solver collocates second derivatives and needs degree >= 2 (even "
                                        "degrees converge best), got " + std::to_string(p));
  const auto& k0 = c0.knots();
  const std::size_t n0 = c0.points().size();
  const int q = c0.degree();
  for (int i = 1; i <= q; ++i)
    if (k0[i] != k0[0] || k0[n0 + q - i] != k0[n0 + q])
      s.fail(path + ".centerline.knots", "the rod solver needs clamped (open) knot vectors, the first and last " +
                                             std::to_string(q + 1) + " knots equal, so the ends are collocation points");
  for (std::size_t i = q + 1; i < n0;) {
    std::size_t m = 1;
    while (i + m < n0 && k0[i + m] == k0[i]) ++m;
    const double turn = std::acos(std::clamp(sideTangent(c0, k0[i], -1).dot(sideTangent(c0, k0[i], 1)), -1.0, 1.0));
    const bool corner = turn > 1e-6;
    const bool site = std::binary_search(sites.begin(), sites.end(), k0[i]);
    // At a site the rod has one rotation, which cannot follow a frame that turns there with the
    // tangent (rotation-minimizing: a 90-degree corner loaded there was 2.5 % off at any spans; a
    // milliradian costs under 2e-5). A given orientation is continuous, and the kink a reference shear
    // (a deformed design's at a T-joint: 0.46 degrees in the tests), up to a tenth of a radian.
    const double largest = rod.frame().kind() == geometry::RodFrame::Kind::Orientation ? 0.1 : 1e-3;
    if (m >= static_cast<std::size_t>(q) && site && turn > largest)
      s.fail(path + ".centerline.knots[" + std::to_string(i) + "]",
             "the centerline turns by " + format(turn * 180 / std::numbers::pi) + " degrees at u = " + format(k0[i]) +
                 ", where a load, support or joint acts on it, and its frame with it (at most " +
                 format(largest * 180 / std::numbers::pi) + " degrees there): the rod's one rotation there cannot "
                 "follow both sides; split the rod there (rods joined at a corner are coupled rigidly)");
    if (m >= static_cast<std::size_t>(q) && (!rebuild || corner) && !site)
      s.fail(path + ".centerline.knots[" + std::to_string(i) + "]",
             "knot " + format(k0[i]) + " repeated " + std::to_string(m) + " times makes " +
                 (corner ? "a corner" : "the curve only C0 on its own basis, which") + " the collocation cannot resolve; " +
                 (corner ? "split the rod there (rods joined at a corner are coupled rigidly)"
                         : "rebuild it with --degree (the default) or split the rod there"));
    i += m;
  }
}

// Convergence order of collocation at degree p: p for even degrees, p - 1 for odd ones.
int collocationOrder(int p) { return p % 2 == 0 ? p : p - 1; }

// Total turning of the drawn centerline's tangent (rad), from a dense sampling.
double drawnTurning(const geometry::NurbsCurve& c) {
  const int samples = 32 * static_cast<int>(c.breakpoints().size());
  double turning = 0.0;
  Vec3 previous = sideTangent(c, c.domainBegin(), 1);
  for (int i = 1; i <= samples; ++i) {
    const Vec3 t = sideTangent(c, c.domainBegin() + (c.domainEnd() - c.domainBegin()) * i / samples, -1);
    turning += std::atan2(previous.cross(t).norm(), previous.dot(t));
    previous = t;
  }
  return turning;
}

// Smallest section dimension (mm): the thickness that governs a rod's slenderness.
double thickness(const geometry::Section& section) { return std::min(section.width, section.height); }

}  // namespace

// Shortest length over which the modulus changes by its own size: min E / |dE/ds| (mm), infinite
// for a constant E. Where E falls steeply the curvature M / (E I) nears a pole just beyond the rod
// and polynomials need spans far shorter than this length to follow it.
double modulusLength(const geometry::Rod& rod) {
  const geometry::BSplineField& e = rod.modulus();
  if (e.isConstant()) return std::numeric_limits<double>::infinity();
  const geometry::NurbsCurve& c = rod.centerline();
  const int samples = 32 * static_cast<int>(e.values().size() + c.breakpoints().size());
  double shortest = std::numeric_limits<double>::infinity();
  for (int i = 0; i <= samples; ++i) {
    const double u = c.domainBegin() + (c.domainEnd() - c.domainBegin()) * i / samples;
    Vec3 d[2];
    c.derivatives(u, 1, d);
    const double slope = std::abs(e.derivative(u)) / std::max(d[1].norm(), 1e-300);  // |dE/ds|
    if (slope > 0) shortest = std::min(shortest, std::abs(e.value(u)) / slope);
  }
  return shortest;
}

// Collocation of primal Cosserat rods locks: the error of a rod of slenderness L/d whose tangent
// turns by theta grows like (L/d)^2 (theta / N)^q for N spans of order q, and a modulus that falls
// steeply needs spans short against E / |dE/ds| (mechanics/README.md: measured on straight,
// curved and graded cantilevers from L/d = 10 to 1000). Spans for the relative accuracy
// `tolerance`, with s = (1e-4 / tolerance)^(1/q):
//   N = max(c_q (L/d)^(2/q) max(theta, 1.2) s, e_q (L / (E / |dE/ds|)) s),
// theta at least 1.2 rad because the load bends straight rods too; c_q and e_q were fitted to reach
// 1e-4 on every measured case.
double aPrioriSpans(const geometry::Rod& rod, int degree, double tolerance) {
  const int q = collocationOrder(degree);
  const double c = q <= 2 ? 57.0 : q <= 4 ? 8.1 : 3.0;
  const double e = q <= 2 ? 60.0 : q <= 4 ? 11.0 : 3.0;
  const double scale = std::pow(1e-4 / tolerance, 1.0 / q);
  const double slenderness = std::max(1.0, rod.length() / thickness(rod.section()));
  const double theta = std::max(drawnTurning(rod.centerline()), 1.2);
  const double locking = c * std::pow(slenderness, 2.0 / q) * theta * scale;
  const double grading = e * rod.length() / modulusLength(rod) * scale;
  return std::max(locking, grading);
}

// The a priori spans, at least 4, one per design span and two per span of E(s).
int automaticSpans(const geometry::Rod& rod, int degree, double tolerance) {
  const int designSpans = static_cast<int>(rod.centerline().breakpoints().size()) - 1;
  const int modulusSpans = rod.modulus().isConstant()
                               ? 0
                               : static_cast<int>(rod.modulus().values().size()) - rod.modulus().degree();
  const double spans =
      std::max({4.0, std::ceil(aPrioriSpans(rod, degree, tolerance)), double(designSpans), 2.0 * modulusSpans});
  return spans > kMaxSpansPerRod ? kMaxSpansPerRod + 1 : static_cast<int>(spans);
}

namespace {

// Automatic refinement of a design's own basis beyond this many spans per rod is refused.
constexpr int kMaxAutomaticDesignSpans = 256;

// Parameters where E(s) has a kink (a knot of multiplicity >= its degree) inside the domain.
std::vector<double> modulusKinks(const geometry::BSplineField& e) {
  std::vector<double> kinks;
  if (e.isConstant()) return kinks;
  const auto& ek = e.knots();
  for (std::size_t i = e.degree() + 1; i < e.values().size();) {
    std::size_t m = 1;
    while (i + m < e.values().size() && ek[i + m] == ek[i]) ++m;
    if (m >= static_cast<std::size_t>(e.degree()) && ek[i] > e.domainBegin() && ek[i] < e.domainEnd()) kinks.push_back(ek[i]);
    i += m;
  }
  return kinks;
}

// Parameters inside the domain where a drawn centerline of degree 2 or more is only C0 or C1 (a knot
// of multiplicity >= its degree - 1: every knot of a quadratic, the double knots of the rational
// circle CAD writes): there r(u) has a kink in r'' (the circle's parametric speed turns with it), which
// a rebuilt basis smooth across it interpolates only to order h^2 (a 20 mm ring drawn so was 2e-3 mm
// off its own circle, the written design with it, at the default spans). A C1 knot of the rebuilt
// basis follows it. Not for polylines (a C0 speed jump no C1 knot follows), and not where the drawing
// has more such knots than the rebuilt rod has spans (a quadratic of 4,000 spans would multiply the
// unknowns by p - 1 = 5): none are returned then.
std::vector<double> drawnKinks(const geometry::NurbsCurve& c, int spans) {
  std::vector<double> kinks;
  if (c.degree() < 2) return kinks;
  const auto& k = c.knots();
  const std::size_t count = c.points().size();
  const auto least = static_cast<std::size_t>(c.degree() - 1);
  for (std::size_t i = static_cast<std::size_t>(c.degree()) + 1; i < count;) {
    std::size_t m = 1;
    while (i + m < count && k[i + m] == k[i]) ++m;
    if (m >= least) kinks.push_back(k[i]);
    i += m;
  }
  if (kinks.size() > static_cast<std::size_t>(spans)) kinks.clear();
  return kinks;
}

// Knots of a rebuilt rod: `spans` spans, uniform between the breaks (modulus kinks and interior
// sites), each piece getting spans in proportion to its length (at least one). At a kink of E the
// solution's curvature has a kink too (kappa = m / (E I)): the knot is repeated p - 1 times there,
// so the basis is only C1 and can follow it (with a plain knot convergence falls to order 2.5), and
// no collocation point (a mean of p consecutive knots) lands on it. At an interior site the knot is
// repeated p times: the basis is C0, so r' and q' (n and m) may jump there by the point force and
// moment of the node, and the control point there is the site's, carrying the node's rows.
std::vector<double> rebuiltKnots(double begin, double end, int p, int spans, const std::vector<double>& kinks,
                                 const std::vector<double>& sites) {
  std::vector<std::pair<double, int>> inner;  // parameter, multiplicity
  for (double k : kinks) inner.emplace_back(k, std::max(1, p - 1));
  for (double u : sites) inner.emplace_back(u, p);
  std::sort(inner.begin(), inner.end());
  std::vector<double> breaks = {begin};
  std::vector<int> multiplicity = {0};
  const double same = 1e-12 * (end - begin);
  for (const auto& [u, m] : inner) {
    if (u - breaks.back() <= same) multiplicity.back() = std::max(multiplicity.back(), m);
    else breaks.push_back(u), multiplicity.push_back(m);
  }
  breaks.push_back(end);
  const int pieces = static_cast<int>(breaks.size()) - 1;
  spans = std::max(spans, pieces);
  std::vector<double> knots(p + 1, begin);
  int given = 0;
  for (int i = 0; i < pieces; ++i) {
    // Spans up to the end of piece i in proportion to length, each piece at least one.
    const int upTo = i + 1 == pieces ? spans
                                     : std::clamp(static_cast<int>(std::lround(spans * (breaks[i + 1] - begin) / (end - begin))),
                                                  given + 1, spans - (pieces - i - 1));
    for (int k = 1; k < upTo - given; ++k) knots.push_back(breaks[i] + (breaks[i + 1] - breaks[i]) * k / (upTo - given));
    if (i + 1 < pieces) knots.insert(knots.end(), multiplicity[i + 1], breaks[i + 1]);
    given = upTo;
  }
  knots.insert(knots.end(), p + 1, end);
  return knots;
}

// The design's curve refined by knot insertion, each interior site's knot raised to multiplicity p.
geometry::NurbsCurve refinedWithSites(const geometry::NurbsCurve& c0, int insertionsPerSpan, const std::vector<double>& sites) {
  geometry::NurbsCurve curve = c0.refined(insertionsPerSpan);
  for (double u : sites) {
    const auto& k = curve.knots();
    for (auto m = std::count(k.begin(), k.end(), u); m < curve.degree(); ++m) curve = curve.withKnotInserted(u);
  }
  return curve;
}

}  // namespace

RodBasisChoice chooseBasis(const DiscreteStructure& s, const geometry::Rod& rod, std::size_t index,
                           const Discretization& d, const std::string& path) {
  const geometry::NurbsCurve& c0 = rod.centerline();
  RodBasisChoice choice;
  choice.rebuild = d.degree > 0;
  choice.degree = choice.rebuild ? d.degree : c0.degree();
  checkCenterline(s, rod, choice.degree, choice.rebuild, path, s.interiorSites[index]);
  const int designSpans = static_cast<int>(c0.breakpoints().size()) - 1;
  if (index < d.perRod.size()) choice.spans = d.perRod[index];
  else if (choice.rebuild && d.spans > 0) choice.spans = d.spans;
  else if (choice.rebuild) {
    choice.spans = automaticSpans(rod, choice.degree, d.tolerance);
    if (choice.spans > kMaxSpansPerRod)
      s.fail(path, "at degree " + std::to_string(choice.degree) + " this rod would need more than " +
                       std::to_string(kMaxSpansPerRod) + " spans for the accuracy asked; " +
                       (choice.degree < 7 ? "use a higher --degree (up to 7) or a looser --accuracy" : "use a looser --accuracy"));
  }
  else if (d.refine >= 0) choice.spans = d.refine + 1;
  else {
    // On its own basis a rod keeps its degree; a low one may need more spans than is sensible.
    const int total = automaticSpans(rod, choice.degree, d.tolerance);
    if (total > kMaxAutomaticDesignSpans)
      s.fail(path + ".centerline.degree",
             "on its own degree-" + std::to_string(choice.degree) + " basis (--degree 0) this rod would need more than " +
                 std::to_string(kMaxAutomaticDesignSpans) + " spans for the default accuracy (collocation converges at order " +
                 std::to_string(collocationOrder(choice.degree)) + " at this degree); rebuild it with --degree 6, or "
                 "give --refine to accept a coarser answer");
    choice.spans = (total + designSpans - 1) / designSpans;
  }
  if (choice.spans < 1 || (choice.rebuild ? choice.spans : choice.spans * designSpans) > kMaxSpansPerRod)
    s.fail(path, "a solver basis of " + std::to_string(choice.spans * (choice.rebuild ? 1 : designSpans)) +
                     " spans is out of range (1.." + std::to_string(kMaxSpansPerRod) + " per rod)");
  return choice;
}

geometry::NurbsCurve solverCurve(const geometry::Rod& rod, const RodBasisChoice& choice, const std::vector<double>& sites) {
  const geometry::NurbsCurve& c0 = rod.centerline();
  if (!choice.rebuild) return refinedWithSites(c0, choice.spans - 1, sites);
  std::vector<double> kinks = modulusKinks(rod.modulus());
  for (double u : drawnKinks(c0, choice.spans)) kinks.push_back(u);
  std::vector<double> knots = rebuiltKnots(c0.domainBegin(), c0.domainEnd(), choice.degree, choice.spans, kinks, sites);
  const std::size_t count = knots.size() - choice.degree - 1;
  return geometry::NurbsCurve(choice.degree, std::move(knots), std::vector<Vec3>(count, Vec3::Zero()));
}

std::vector<double> grevilleAbscissae(const geometry::NurbsCurve& curve) {
  const int p = curve.degree(), count = static_cast<int>(curve.points().size());
  const auto& knots = curve.knots();
  std::vector<double> tau(count);
  for (int j = 0; j < count; ++j) {
    double sum = 0;
    for (int i = 1; i <= p; ++i) sum += knots[j + i];
    tau[j] = sum / p;
  }
  tau.front() = curve.domainBegin();
  tau.back() = curve.domainEnd();
  return tau;
}

std::vector<int> sitePoints(const geometry::NurbsCurve& curve, std::vector<double>& sites, std::vector<double>& tau) {
  const auto& knots = curve.knots();
  const double same = 1e-12 * (curve.domainEnd() - curve.domainBegin());
  std::vector<int> points;
  for (double& u : sites) {
    const int k = static_cast<int>(std::lower_bound(knots.begin(), knots.end(), u - same) - knots.begin()) - 1;
    points.push_back(k);
    u = tau[k] = knots[k + 1];
  }
  return points;
}

std::optional<double> kinkAtCollocationPoint(const geometry::BSplineField& e, const std::vector<double>& tau,
                                             const std::vector<int>& sitePoints) {
  const double scale = std::max(1.0, std::abs(e.domainEnd() - e.domainBegin()));
  for (double kink : modulusKinks(e))
    for (std::size_t j = 0; j < tau.size(); ++j)
      if (std::abs(tau[j] - kink) <= 1e-12 * scale &&
          !std::count(sitePoints.begin(), sitePoints.end(), static_cast<int>(j)))
        return kink;
  return std::nullopt;
}

}  // namespace rodfab::mechanics::detail
