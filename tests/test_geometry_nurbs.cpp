// geometry/: the fixed-degree NURBS paths (degrees 1..3, orders 0..2) against the general algorithm
// (nurbs_reference.hpp), bit for bit.
#include "geometry/geometry.hpp"
#include "geometry/nurbs_reference.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

using namespace rodfab::geometry;

namespace {

// A random clamped curve: 1..4 interior breakpoints, each repeated 1..degree times (so kinks and every
// lower continuity occur), control points in [-10, 10]^3, weights in [0.2, 5] when rational.
NurbsCurve randomCurve(int degree, bool rational, std::mt19937& rng) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  double t = -0.3;
  std::vector<double> knots(degree + 1, t);
  const int breaks = 1 + static_cast<int>(rng() % 4);
  for (int b = 0; b < breaks; ++b) {
    t += 0.05 + uni(rng);
    knots.insert(knots.end(), 1 + rng() % degree, t);
  }
  t += 0.05 + uni(rng);
  knots.insert(knots.end(), degree + 1, t);
  std::vector<Vec3> points;
  std::vector<double> weights;
  for (std::size_t i = 0; i + degree + 1 < knots.size(); ++i) {
    points.emplace_back(20 * uni(rng) - 10, 20 * uni(rng) - 10, 20 * uni(rng) - 10);
    if (rational) weights.push_back(0.2 + 4.8 * uni(rng));
  }
  return NurbsCurve(degree, knots, points, weights);
}

// The span NurbsCurve::derivativesFromBelow evaluates in: the one whose closure ends at (or holds) u.
int spanFromBelow(const NurbsCurve& c, double u) {
  const int count = static_cast<int>(c.points().size());
  if (u <= c.domainBegin()) return findKnotSpan(c.knots(), c.degree(), count, u);
  const auto first = c.knots().begin() + c.degree(), last = c.knots().begin() + count;
  return static_cast<int>(std::lower_bound(first, last, u) - c.knots().begin()) - 1;
}

// The curve's derivatives from the general basis, in the homogeneous form of NurbsCurve's evaluation,
// operation for operation.
void referenceDerivatives(const NurbsCurve& c, int span, double u, int order, Vec3* out) {
  BasisDerivatives ders;
  basisFunctionDerivativesAnyDegree(c.knots(), c.degree(), span, u, order, ders);
  Vec3 a[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  double w[3] = {0.0, 0.0, 0.0};
  for (int j = 0; j <= c.degree(); ++j) {
    const int i = span - c.degree() + j;
    for (int k = 0; k <= order; ++k) {
      a[k] += (ders[k][j] * c.weights()[i]) * c.points()[i];
      w[k] += ders[k][j] * c.weights()[i];
    }
  }
  out[0] = a[0] / w[0];
  if (order >= 1) out[1] = (a[1] - w[1] * out[0]) / w[0];
  if (order >= 2) out[2] = (a[2] - 2.0 * w[1] * out[1] - w[2] * out[0]) / w[0];
}

bool sameBits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }
bool sameBits(const Vec3& a, const Vec3& b) { return sameBits(a.x(), b.x()) && sameBits(a.y(), b.y()) && sameBits(a.z(), b.z()); }

}  // namespace

TEST_CASE("NURBS basis and curve evaluation equal the general algorithm bit for bit at every degree", "[nurbs]") {
  std::mt19937 rng(2026);
  long compared = 0, basisMismatches = 0, curveMismatches = 0, kinkedSpans = 0;
  for (int degree = 1; degree <= kMaxDegree; ++degree)
    for (bool rational : {false, true})
      for (int trial = 0; trial < 4; ++trial) {
        const NurbsCurve c = randomCurve(degree, rational, rng);
        REQUIRE(c.isRational() == rational);
        // Random parameters, every knot of the domain (where the spans from above and below differ) and its neighbours.
        std::vector<double> us;
        std::uniform_real_distribution<double> inDomain(c.domainBegin(), c.domainEnd());
        for (int k = 0; k < 200; ++k) us.push_back(inDomain(rng));
        for (double knot : c.knots()) {
          us.push_back(knot);
          us.push_back(std::nextafter(knot, -std::numeric_limits<double>::infinity()));
          us.push_back(std::nextafter(knot, std::numeric_limits<double>::infinity()));
        }
        for (double u : us) {
          u = std::clamp(u, c.domainBegin(), c.domainEnd());
          const int above = findKnotSpan(c.knots(), degree, static_cast<int>(c.points().size()), u);
          const int below = spanFromBelow(c, u);
          kinkedSpans += above != below;
          for (bool fromBelow : {false, true})
            for (int order = 0; order <= 2; ++order) {
              const int span = fromBelow ? below : above;
              BasisDerivatives fast, general;
              basisFunctionDerivatives(c.knots(), degree, span, u, order, fast);
              basisFunctionDerivativesAnyDegree(c.knots(), degree, span, u, order, general);
              for (int k = 0; k <= order; ++k)
                for (int j = 0; j <= degree; ++j) basisMismatches += !sameBits(fast[k][j], general[k][j]);
              Vec3 got[3], want[3];
              if (fromBelow) c.derivativesFromBelow(u, order, got);
              else c.derivatives(u, order, got);
              referenceDerivatives(c, span, u, order, want);
              for (int k = 0; k <= order; ++k) curveMismatches += !sameBits(got[k], want[k]);
              ++compared;
            }
        }
      }
  INFO(compared << " evaluations compared");
  CHECK(basisMismatches == 0);
  CHECK(curveMismatches == 0);
  CHECK(kinkedSpans > 0);  // the knots were hit, so the spans from below were exercised
  // The comparison sees single-ulp differences: the neighbouring parameter gives other bits.
  const NurbsCurve c = randomCurve(3, true, rng);
  const double u = 0.5 * (c.domainBegin() + c.domainEnd());
  Vec3 here[3], next[3];
  c.derivatives(u, 2, here);
  c.derivatives(std::nextafter(u, c.domainEnd()), 2, next);
  CHECK_FALSE(sameBits(here[0], next[0]));
}
