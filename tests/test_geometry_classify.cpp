// geometry/: Rod::classify, which examines only the sample segments whose boxes hold the point, against
// the walk over every segment (the same test before the boxes), bit for bit; SegmentBoxes against
// checking every box.
#include "geometry/geometry.hpp"
#include "geometry/segment_boxes.hpp"
#include "tests/test_geometry_curves.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <utility>

using namespace rodfab::geometry;
using rodfab::geometry::testing::helix;

namespace {

Rod rodOf(const std::string& name, NurbsCurve c, Section section, CapStyle caps) {
  return Rod(name, std::move(c), section, std::nullopt, std::nullopt, caps, BSplineField::constant(5, 0, 1));
}

// The rods of the test: a long helix (many samples), a tight one whose axis is near the centres of
// curvature (the fold path), a U-turn of radius just above the section's, a kinked polyline with flat
// caps and a rectangular rod with a C0 knot.
std::vector<Rod> testRods() {
  std::vector<Rod> rods;
  rods.push_back(rodOf("helix", helix(4.0, 1.5, 20.0, 12), Section::circle(1.2), CapStyle::Round));
  rods.push_back(rodOf("tight helix", helix(0.55, 1.2, 4.0, 12), Section::ellipse(1.0, 0.7), CapStyle::Round));
  const double w = std::sqrt(0.5);
  rods.push_back(rodOf("u-turn",
                       NurbsCurve(2, {0, 0, 0, 0.5, 0.5, 1, 1, 1}, {{0, -0.6, 0}, {0.6, -0.6, 0}, {0.6, 0, 0}, {0.6, 0.6, 0}, {0, 0.6, 0}},
                                  {1, w, 1, w, 1}),
                       Section::circle(1.1), CapStyle::Round));
  rods.push_back(rodOf("kinked", NurbsCurve(1, {0, 0, 0.25, 0.5, 0.75, 1, 1}, {{0, 0, 0}, {2, 0, 0}, {2.3, 1, 0.2}, {0.5, 1.5, -0.5}, {0.5, 0.2, 1}}),
                       Section::circle(0.6), CapStyle::Flat));
  rods.push_back(Rod("rect", NurbsCurve(2, {0, 0, 0, 0.5, 0.5, 1, 1, 1}, {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 1, 0.5}, {1, 2, 1}}),
                     Section::rectangle(0.9, 0.3), Vec3(0, 0, 1), std::nullopt, CapStyle::Round, BSplineField::constant(5, 0, 1)));
  return rods;
}

bool sameBits(const RodHit& a, const RodHit& b) {
  return a.inside == b.inside && std::bit_cast<std::uint64_t>(a.depth) == std::bit_cast<std::uint64_t>(b.depth) &&
         std::bit_cast<std::uint64_t>(a.u) == std::bit_cast<std::uint64_t>(b.u);
}

}  // namespace

TEST_CASE("classify gives the bits of the walk over every segment, near and far from the rod", "[rod][classify]") {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> unit(0.0, 1.0), offset(-1.0, 1.0);
  for (const Rod& rod : testRods()) {
    INFO(rod.name());
    const double reach = rod.section().boundingRadius();
    const double u0 = rod.centerline().domainBegin(), u1 = rod.centerline().domainEnd();
    const Box3 b = rod.bounds();
    int inside = 0, tried = 0;
    auto check = [&](const Vec3& p) {
      const RodHit hit = rod.classify(p), walk = rod.classifyWalkingEverySegment(p);
      CAPTURE(p.x(), p.y(), p.z(), hit.depth, walk.depth, hit.u, walk.u);
      REQUIRE(sameBits(hit, walk));
      inside += hit.inside;
      ++tried;
    };
    for (int n = 0; n < 6000; ++n) {
      // Around the centerline, up to twice the section's reach: the boundary, the inside, the caps.
      const Vec3 c = rod.centerline().point(u0 + (u1 - u0) * std::clamp(1.1 * unit(rng) - 0.05, 0.0, 1.0));
      check(c + 2.0 * reach * Vec3(offset(rng), offset(rng), offset(rng)));
      // Anywhere in (and a little beyond) the bounds: far points, and the centres of curvature.
      check(Vec3(b.min().x() - 1 + (b.sizes().x() + 2) * unit(rng), b.min().y() - 1 + (b.sizes().y() + 2) * unit(rng),
                 b.min().z() - 1 + (b.sizes().z() + 2) * unit(rng)));
    }
    // The end points and just beyond them: the caps and the end planes.
    for (const double u : {u0, u1}) {
      Vec3 d[2];
      rod.centerline().derivatives(u, 1, d);
      const Vec3 t = d[1].normalized();
      for (const double along : {-0.3, 0.0, 1e-12, 0.2, 0.5, 0.7})
        for (int k = 0; k < 20; ++k) check(d[0] + (u == u0 ? -along : along) * t + 0.4 * reach * Vec3(offset(rng), offset(rng), offset(rng)));
    }
    REQUIRE(inside > tried / 20);  // the comparison covers the inside, not only far points
  }
  // A point with a non-finite coordinate is in no box: classify walks for it, as before.
  const Rod longHelix = testRods().front();
  for (const double bad : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()})
    REQUIRE(sameBits(longHelix.classify(Vec3(bad, 0, 1)), longHelix.classifyWalkingEverySegment(Vec3(bad, 0, 1))));
}

TEST_CASE("The tight helix's axis takes the fold path, and classify matches the walk there", "[rod][classify]") {
  // On the axis of a helix of radius 0.55 with a section of reach 0.5 every point is within the
  // segments' reach at a curvature radius of ~0.6: the crossing search subdivides (kFoldSubdivisions).
  const Rod rod = testRods()[1];
  int insideOnAxis = 0, insideNear = 0;
  for (int k = 0; k <= 400; ++k) {
    for (const double r : {0.0, 0.05, 0.1}) {
      const Vec3 p(r, -r, 4.0 * 1.2 * k / 400.0);
      const RodHit hit = rod.classify(p);
      CAPTURE(p.z(), r);
      REQUIRE(sameBits(hit, rod.classifyWalkingEverySegment(p)));
      (r == 0.0 ? insideOnAxis : insideNear) += hit.inside;
    }
  }
  // The axis is ~0.53 from the centerline (the spline runs inside its points' circle), beyond the
  // ellipse's half-axes (0.5, 0.35); 0.07 to 0.14 off the axis some sections reach.
  REQUIRE(insideOnAxis == 0);
  REQUIRE(insideNear > 0);
}

TEST_CASE("A coil tighter than its section: classify skips the far turns and still gives the walk's bits", "[rod][classify][coil]") {
  // Every point of such a coil is within reach of every turn nearby, so classify takes the segments
  // nearest first and skips those whose hull is too far for a section as deep as the best so far;
  // ties go to the lowest u in any order. Circles, ellipses and rectangles, E varying along the rod
  // (so u decides the value), pitches below and near the section, and points on the axis.
  const BSplineField ramp(1, {0, 0, 0.5, 1, 1}, {20, 200, 30});
  std::vector<Rod> rods;
  rods.push_back(Rod("coil 0.2 / 1.0", helix(0.2, 0.063, 8, 21), Section::circle(2.0), std::nullopt, std::nullopt, CapStyle::Round, ramp));
  rods.push_back(Rod("coil 0.3 / ellipse", helix(0.3, 0.1, 6, 16), Section::ellipse(1.4, 0.9), Vec3(0, 0, 1), std::nullopt,
                     CapStyle::Flat, ramp));
  rods.push_back(Rod("coil 0.5 / rectangle", helix(0.5, 0.4, 5, 12), Section::rectangle(1.6, 0.8), Vec3(0, 0, 1), std::nullopt,
                     CapStyle::Round, ramp));
  rods.push_back(Rod("coil 0.1 / 0.4, pitch 0.02", helix(0.1, 0.02, 10, 24), Section::circle(0.8), std::nullopt, std::nullopt,
                     CapStyle::Round, ramp));
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const Rod& rod : rods) {
    INFO(rod.name());
    const Box3 b = rod.bounds();
    int inside = 0;
    auto check = [&](const Vec3& p) {
      const RodHit hit = rod.classify(p), walk = rod.classifyWalkingEverySegment(p);
      CAPTURE(p.x(), p.y(), p.z(), hit.depth, walk.depth, hit.u, walk.u);
      REQUIRE(sameBits(hit, walk));
      inside += hit.inside;
    };
    for (int n = 0; n < 1500; ++n) {
      const Vec3 margin = Vec3::Constant(0.2);
      check(Vec3(b.min() - margin) + Vec3((b.sizes() + 2 * margin).array() * Vec3(unit(rng), unit(rng), unit(rng)).array()));
      check(Vec3(0.0, 0.0, b.min().z() + b.sizes().z() * unit(rng)));
    }
    REQUIRE(inside > 1000);
  }
}

namespace {

// A rational coil: quadratic arcs of a quarter turn (the circle's corner weights cos 45 degrees, times
// a random factor in [0.5, 2] when `skewed`: kinks at the arcs' joints then), rising `pitch` a turn.
NurbsCurve rationalCoil(double radius, double pitch, int quarters, bool skewed, std::mt19937& rng) {
  std::uniform_real_distribution<double> factor(0.5, 2.0);
  std::vector<Vec3> points;
  std::vector<double> weights, knots{0, 0, 0};
  for (int q = 0;; ++q) {
    const double angle = q * std::numbers::pi / 2, corner = angle + std::numbers::pi / 4;
    points.emplace_back(radius * std::cos(angle), radius * std::sin(angle), pitch * q / 4);
    weights.push_back(1.0);
    if (q == quarters) break;
    points.emplace_back(radius * std::sqrt(2.0) * std::cos(corner), radius * std::sqrt(2.0) * std::sin(corner), pitch * (q + 0.5) / 4);
    weights.push_back(std::sqrt(0.5) * (skewed ? factor(rng) : 1.0));
    if (q + 1 < quarters) knots.insert(knots.end(), 2, q + 1.0);
  }
  knots.insert(knots.end(), 3, static_cast<double>(quarters));
  return NurbsCurve(2, knots, points, weights);
}

}  // namespace

TEST_CASE("Random coils tighter than their section, polynomial and rational - classify is the walk, bit for bit", "[rod][classify][coil]") {
  // The hulls' capsules (chord and Bezier deviation) let classify skip most segments of such a coil:
  // a deviation bound too small, or a node's capsule not holding its segments, skips the deepest
  // section for some point, and its bits differ from the walk's.
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const BSplineField ramp(1, {0, 0, 0.5, 1, 1}, {20, 200, 30});
  for (int trial = 0; trial < 12; ++trial) {
    const double radius = 0.05 + 0.45 * unit(rng), pitch = radius * (0.05 + 1.2 * unit(rng));
    const double reach = radius * (1.2 + 5.0 * unit(rng));
    const NurbsCurve centerline = trial % 3 == 2 ? rationalCoil(radius, pitch, 8 + trial, trial % 2 == 1, rng)
                                                 : helix(radius, pitch, 3.0 + 5.0 * unit(rng), 8 + static_cast<int>(20 * unit(rng)));
    const Section section = trial % 4 == 0 ? Section::rectangle(1.6 * reach, 0.9 * reach)
                            : trial % 4 == 1 ? Section::ellipse(2.0 * reach, 1.2 * reach)
                                             : Section::circle(2.0 * reach);
    const Rod rod("random coil", centerline, section, Vec3(0, 0, 1), std::nullopt, trial % 2 ? CapStyle::Flat : CapStyle::Round, ramp);
    const Box3 b = rod.bounds();
    const double u0 = centerline.domainBegin(), u1 = centerline.domainEnd();
    int inside = 0;
    auto check = [&](const Vec3& p) {
      const RodHit hit = rod.classify(p), walk = rod.classifyWalkingEverySegment(p);
      CAPTURE(trial, radius, pitch, reach, p.x(), p.y(), p.z(), hit.depth, walk.depth, hit.u, walk.u);
      REQUIRE(sameBits(hit, walk));
      inside += hit.inside;
    };
    for (int n = 0; n < 5000; ++n) {
      check(Vec3(b.min() + Vec3(b.sizes().array() * Vec3(unit(rng), unit(rng), unit(rng)).array())));
      check(Vec3(radius * (unit(rng) - 0.5), radius * (unit(rng) - 0.5), b.min().z() + b.sizes().z() * unit(rng)));
      const Vec3 c = centerline.point(u0 + (u1 - u0) * unit(rng));
      check(c + 1.2 * reach * Vec3(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5));
    }
    REQUIRE(inside > 300);
  }
}

TEST_CASE("NurbsCurve::deviationOn holds the curve on the interval within it of the chord, and is tight on a short one", "[rod][classify]") {
  // Every C(u) of [a, b] lies within deviationOn of the chord C(a) C(b): on a helix, rational arcs, a
  // cubic with weights 1e-2 to 1e3 and a kink, and a rational quintic with random weights (a bound
  // from the homogeneous points, or from sampled points only, fails here).
  const double w = std::sqrt(0.5);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> wild;
  std::vector<double> weights;
  for (int i = 0; i < 12; ++i) {
    wild.emplace_back(unit(rng), unit(rng), unit(rng));
    weights.push_back(std::exp(6.0 * unit(rng) - 3.0));
  }
  const NurbsCurve curves[] = {
      helix(0.2, 0.063, 3, 21),
      NurbsCurve(2, {0, 0, 0, 0.5, 0.5, 1, 1, 1}, {{0, -0.6, 0}, {0.6, -0.6, 0}, {0.6, 0, 0}, {0.6, 0.6, 0}, {0, 0.6, 0}}, {1, w, 1, w, 1}),
      NurbsCurve(3, {0, 0, 0, 0, 0.3, 0.3, 0.3, 1, 1, 1, 1}, {{0, 0, 0}, {1, 2, 0}, {2, 0, 1}, {3, 1, 0}, {2, 3, 2}, {0, 1, 1}, {1, 0, 0}},
                 {1, 1e3, 2, 1, 5, 1e-2, 1}),
      NurbsCurve(5, {0, 0, 0, 0, 0, 0, 0.2, 0.4, 0.4, 0.6, 0.8, 0.9, 1, 1, 1, 1, 1, 1}, wild, weights),
  };
  for (const NurbsCurve& c : curves) {
    const double u0 = c.domainBegin(), u1 = c.domainEnd();
    for (int n = 0; n < 300; ++n) {
      double a = u0 + (u1 - u0) * unit(rng), b = u0 + (u1 - u0) * unit(rng);
      if (n % 3 == 0) b = a + (b - a) * 1e-3;
      if (a > b) std::swap(a, b);
      const Vec3 from = c.point(a), to = c.point(b);
      const double deviation = c.deviationOn(a, b, from, to);
      const double tolerance = 1e-12 * (1.0 + std::max(from.cwiseAbs().maxCoeff(), to.cwiseAbs().maxCoeff()));
      double sampled = 0.0;
      for (int k = 0; k <= 256; ++k) {
        const Vec3 q = c.point(a + (b - a) * k / 256.0);
        const Vec3 chord = to - from;
        const double t = chord.squaredNorm() > 0.0 ? std::clamp((q - from).dot(chord) / chord.squaredNorm(), 0.0, 1.0) : 0.0;
        sampled = std::max(sampled, (from + t * chord - q).norm());
      }
      CAPTURE(a, b, deviation, sampled);
      REQUIRE(sampled <= deviation + tolerance);
      // Tight: the control polygon bulges at most a few times the curve on a short interval.
      if (n % 3 == 0) REQUIRE(deviation <= 4.0 * sampled + 1e-9);
    }
  }
}

TEST_CASE("SegmentBoxes visits exactly the boxes holding the point, and the near hulls, whatever the nodes' capsules", "[rod][classify]") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coord(-10.0, 10.0), size(0.0, 4.0), unit(0.0, 1.0);
  // Hulls along a random walk, or along one straight line (the nodes' capsules as thin as their hulls).
  const std::vector<std::pair<std::size_t, bool>> cases{{0, false},  {1, false},   {3, false},   {4, false},  {5, false},
                                                        {16, false}, {17, false},  {63, false},  {200, false}, {700, false},
                                                        {4, true},   {17, true},   {200, true}};
  for (const auto& [count, straight] : cases) {
    std::vector<Box3> boxes(count);
    std::vector<SegmentBoxes::Capsule> hulls(count);
    for (std::size_t i = 0; i < count; ++i) {
      // A walk, as a polyline's boxes are (along one line when `straight`), and now and then an empty
      // box; each hull from its box's corner, some of them balls.
      const Vec3 step = straight ? Vec3(0.3, -0.2, 0.1) : Vec3(0.3 * Vec3(coord(rng), coord(rng), coord(rng)));
      const Vec3 lo = i == 0 ? Vec3(coord(rng), coord(rng), coord(rng)) : Vec3((straight ? hulls[i - 1].a : boxes[i - 1].center()) + step);
      boxes[i] = Box3(lo, lo + Vec3(size(rng), size(rng), size(rng)));
      const Vec3 along = straight ? step : Vec3(0.2 * Vec3(coord(rng), coord(rng), coord(rng)));
      hulls[i] = {lo, i % 5 == 3 ? lo : Vec3(lo + along), i % 3 == 0 ? 0.0 : size(rng) / 4};
      if (i % 11 == 7) boxes[i].setEmpty();
    }
    const SegmentBoxes tree(boxes, hulls, 1e-12);
    REQUIRE(tree.size() == count);
    for (int n = 0; n < 400; ++n) {
      const Vec3 p = count == 0 ? Vec3::Zero() : Vec3(boxes[n % count].center() + 0.5 * Vec3(coord(rng), coord(rng), coord(rng)));
      const std::size_t first = count == 0 ? 0 : rng() % count, last = first + rng() % (count + 1 - first);
      std::vector<std::size_t> visited, expected;
      tree.forEachContaining(p, first, last, [&](std::size_t i) { visited.push_back(i); });
      for (std::size_t i = first; i < last; ++i)
        if (boxes[i].contains(p)) expected.push_back(i);
      CAPTURE(count, first, last);
      REQUIRE(visited == expected);
      // Nearest first with a fixed limit: the boxes holding p whose hull lies within the limit, every
      // one once (a node's capsule that failed to hold a hull below it would skip some).
      for (const double limit : {std::numeric_limits<double>::infinity(), 3.0 * unit(rng), 0.5, 0.0}) {
        std::vector<std::size_t> nearest, within;
        tree.forEachNearestWithin(p, first, last, [&] { return limit; }, [&](std::size_t i) { nearest.push_back(i); });
        for (const std::size_t i : expected) {
          const Vec3 ab = hulls[i].b - hulls[i].a;
          const double t = ab.squaredNorm() > 0.0 ? std::clamp((p - hulls[i].a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
          if ((hulls[i].a + t * ab - p).norm() - hulls[i].radius <= limit) within.push_back(i);
        }
        std::sort(nearest.begin(), nearest.end());
        CAPTURE(limit);
        REQUIRE(nearest == within);
      }
    }
    std::vector<std::size_t> none;
    tree.forEachContaining(Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0), 0, count, [&](std::size_t i) { none.push_back(i); });
    REQUIRE(none.empty());
  }
  REQUIRE_THROWS_AS(SegmentBoxes(std::vector<Box3>(3), std::vector<SegmentBoxes::Capsule>(2), 0.0), std::invalid_argument);
}

// The section test evaluates r and r' with order 1 where it took order 2 before: the same bits only if
// the lower order computes r and r' as the higher one does, on polynomial, rational and kinked curves,
// from above and from below.
TEST_CASE("NURBS derivatives of order 1 are the bits of order 2's r and r', from above and below", "[rod][classify]") {
  const double w = std::sqrt(0.5);
  const std::vector<NurbsCurve> curves{
      helix(4.0, 1.5, 20.0, 12),
      NurbsCurve(2, {0, 0, 0, 0.5, 0.5, 1, 1, 1}, {{0, -0.6, 0}, {0.6, -0.6, 0}, {0.6, 0, 0}, {0.6, 0.6, 0}, {0, 0.6, 0}}, {1, w, 1, w, 1}),
      NurbsCurve(1, {0, 0, 0.25, 0.5, 0.75, 1, 1}, {{0, 0, 0}, {2, 0, 0}, {2.3, 1, 0.2}, {0.5, 1.5, -0.5}, {0.5, 0.2, 1}}),
      NurbsCurve(3, {0, 0, 0, 0, 0.3, 0.3, 0.3, 1, 1, 1, 1}, {{0, 0, 0}, {0, 0, 0}, {1, 0.5, 0}, {1.5, 1, 0.3}, {2, 1, 1}, {2.5, 0, 1}, {3, 0, 0}})};
  std::mt19937 rng(11);
  for (const NurbsCurve& c : curves) {
    std::uniform_real_distribution<double> at(c.domainBegin(), c.domainEnd());
    std::vector<double> us{c.domainBegin(), c.domainEnd(), 0.25, 0.3, 0.5};
    for (int n = 0; n < 200; ++n) us.push_back(at(rng));
    for (const double u : us) {
      if (u < c.domainBegin() || u > c.domainEnd()) continue;
      Vec3 one[2], two[3], oneBelow[2], twoBelow[3];
      c.derivatives(u, 1, one);
      c.derivatives(u, 2, two);
      for (int k = 0; k < 2; ++k)
        for (int a = 0; a < 3; ++a) CHECK(std::bit_cast<std::uint64_t>(one[k][a]) == std::bit_cast<std::uint64_t>(two[k][a]));
      if (u <= c.domainBegin()) continue;
      c.derivativesFromBelow(u, 1, oneBelow);
      c.derivativesFromBelow(u, 2, twoBelow);
      for (int k = 0; k < 2; ++k)
        for (int a = 0; a < 3; ++a) CHECK(std::bit_cast<std::uint64_t>(oneBelow[k][a]) == std::bit_cast<std::uint64_t>(twoBelow[k][a]));
    }
  }
}

// A centerline whose first two control points coincide has zero speed at its start: the section test
// there takes the tangent from r''. Points on the axis just inside the start, and beside it within the
// radius, are inside; points beyond the radius are not.
TEST_CASE("A rod with zero speed at its end classifies points near that end by the tangent's limit", "[rod][classify]") {
  const NurbsCurve c(2, {0, 0, 0, 1, 1, 1}, {{0, 0, 0}, {0, 0, 0}, {4, 0, 0}});  // r(u) = 4 u^2 x: r'(0) = 0, r''(0) along x
  const Rod rod = rodOf("zero speed", c, Section::circle(1.0), CapStyle::Flat);
  CHECK(rod.classify(Vec3(1e-3, 0, 0)).inside);
  CHECK(rod.classify(Vec3(1e-3, 0.4, 0)).inside);
  CHECK(rod.classify(Vec3(1e-3, 0, -0.4)).inside);
  CHECK_FALSE(rod.classify(Vec3(1e-3, 0.6, 0)).inside);
  CHECK_FALSE(rod.classify(Vec3(-0.1, 0, 0)).inside);  // before the flat end
  CHECK(rod.classify(Vec3(2, 0.45, 0)).inside);
  // Still at its other end: r(u) = (8 u - 4 u^2) x, r'(1) = 0.
  const Rod back = rodOf("zero speed at the end", NurbsCurve(2, {0, 0, 0, 1, 1, 1}, {{0, 0, 0}, {4, 0, 0}, {4, 0, 0}}), Section::circle(1.0),
                         CapStyle::Flat);
  CHECK(back.classify(Vec3(4 - 1e-3, 0, 0)).inside);
  CHECK(back.classify(Vec3(4 - 1e-3, 0.3, 0.3)).inside);
  CHECK_FALSE(back.classify(Vec3(4 - 1e-3, 0.4, 0.4)).inside);
  CHECK_FALSE(back.classify(Vec3(4.1, 0, 0)).inside);
  for (const Rod* r : {&rod, &back})
    for (const double x : {1e-4, 1e-3, 0.01, 0.1, 1.0, 3.9, 3.99, 3.999}) CHECK(r->classify(Vec3(x, 0, 0)).inside == r->classifyWalkingEverySegment(Vec3(x, 0, 0)).inside);
}
