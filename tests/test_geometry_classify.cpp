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

TEST_CASE("NurbsCurve::boundsOn holds the curve on the interval, and is tight on a short one", "[rod][classify]") {
  const double w = std::sqrt(0.5);
  const NurbsCurve curves[] = {
      helix(0.2, 0.063, 3, 21),
      NurbsCurve(2, {0, 0, 0, 0.5, 0.5, 1, 1, 1}, {{0, -0.6, 0}, {0.6, -0.6, 0}, {0.6, 0, 0}, {0.6, 0.6, 0}, {0, 0.6, 0}}, {1, w, 1, w, 1}),
      NurbsCurve(3, {0, 0, 0, 0, 0.3, 0.3, 0.3, 1, 1, 1, 1}, {{0, 0, 0}, {1, 2, 0}, {2, 0, 1}, {3, 1, 0}, {2, 3, 2}, {0, 1, 1}, {1, 0, 0}},
                 {1, 1e3, 2, 1, 5, 1e-2, 1}),
  };
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const NurbsCurve& c : curves) {
    const double u0 = c.domainBegin(), u1 = c.domainEnd();
    for (int n = 0; n < 300; ++n) {
      double a = u0 + (u1 - u0) * unit(rng), b = u0 + (u1 - u0) * unit(rng);
      if (n % 3 == 0) b = a + (b - a) * 1e-3;
      if (a > b) std::swap(a, b);
      const auto [low, high] = c.boundsOn(a, b);
      const double tolerance = 1e-12 * (1.0 + std::max(low.cwiseAbs().maxCoeff(), high.cwiseAbs().maxCoeff()));
      Box3 sampled;
      sampled.setEmpty();
      for (int k = 0; k <= 64; ++k) {
        const Vec3 q = c.point(a + (b - a) * k / 64.0);
        sampled.extend(q);
        REQUIRE((q.array() >= low.array() - tolerance).all());
        REQUIRE((q.array() <= high.array() + tolerance).all());
      }
      // Tight: not much beyond the sampled extent on a short interval (the control polygon's bulge).
      if (n % 3 == 0) REQUIRE((Box3(low, high).sizes() - sampled.sizes()).maxCoeff() <= 1e-3 * (1.0 + sampled.sizes().norm()) + 1e-9);
    }
  }
}

TEST_CASE("SegmentBoxes visits exactly the boxes holding the point, in increasing order", "[rod][classify]") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coord(-10.0, 10.0), size(0.0, 4.0);
  for (const std::size_t count : {0u, 1u, 3u, 4u, 5u, 16u, 17u, 63u, 200u}) {
    std::vector<Box3> boxes(count);
    for (std::size_t i = 0; i < count; ++i) {
      // A walk, as a polyline's boxes are, and now and then an empty box.
      const Vec3 lo = i == 0 ? Vec3(coord(rng), coord(rng), coord(rng)) : Vec3(boxes[i - 1].center() + 0.3 * Vec3(coord(rng), coord(rng), coord(rng)));
      boxes[i] = Box3(lo, lo + Vec3(size(rng), size(rng), size(rng)));
      if (i % 11 == 7) boxes[i].setEmpty();
    }
    const SegmentBoxes tree(boxes);
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
      // Nearest first with a fixed limit (the reach boxes serve as hulls): the boxes holding p within
      // the limit, every one once.
      for (const double limit : {std::numeric_limits<double>::infinity(), 0.5, 0.0}) {
        std::vector<std::size_t> nearest, within;
        tree.forEachNearestWithin(p, first, last, [&] { return limit * limit; }, [&](std::size_t i) { nearest.push_back(i); });
        for (const std::size_t i : expected)
          if (boxes[i].squaredExteriorDistance(p) <= limit * limit) within.push_back(i);
        std::sort(nearest.begin(), nearest.end());
        REQUIRE(nearest == within);
      }
    }
    std::vector<std::size_t> none;
    tree.forEachContaining(Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0), 0, count, [&](std::size_t i) { none.push_back(i); });
    REQUIRE(none.empty());
  }
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
