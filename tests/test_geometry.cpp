// geometry/: NURBS evaluation, frames, sections and closest points against analytic truth.
#include "geometry/geometry.hpp"
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

// Full circle of radius R in the xy-plane centred at c: rational quadratic, 9 control points.
NurbsCurve nurbsCircle(double R, const Vec3& c = Vec3::Zero()) {
  const double w = std::sqrt(0.5);
  std::vector<Vec3> pts = {{R, 0, 0}, {R, R, 0}, {0, R, 0}, {-R, R, 0}, {-R, 0, 0},
                           {-R, -R, 0}, {0, -R, 0}, {R, -R, 0}, {R, 0, 0}};
  for (auto& p : pts) p += c;
  return NurbsCurve(2, {0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1}, pts, {1, w, 1, w, 1, w, 1, w, 1});
}

NurbsCurve wigglyCubic() {
  return NurbsCurve(3, {0, 0, 0, 0, 0.3, 0.5, 0.8, 1, 1, 1, 1},
                    {{0, 0, 0}, {1, 2, 0}, {3, -1, 1}, {4, 2, 2}, {6, 0, 1}, {7, 1, -1}, {8, 3, 0}},
                    {1, 0.7, 1.3, 1, 2, 0.8, 1});
}


}  // namespace

TEST_CASE("A rational quadratic NURBS circle has constant radius and the exact length", "[nurbs]") {
  const double R = 2.5;
  const NurbsCurve c = nurbsCircle(R, Vec3(1, -2, 3));
  for (int k = 0; k <= 1000; ++k) {
    const double u = k / 1000.0;
    REQUIRE((c.point(u) - Vec3(1, -2, 3)).norm() == Approx(R).epsilon(1e-12));
  }
  REQUIRE(c.isRational());
  REQUIRE(c.arcLength() == Approx(2 * std::numbers::pi * R).epsilon(1e-9));
  REQUIRE(c.arcLength(0.0, 0.25) == Approx(0.5 * std::numbers::pi * R).epsilon(1e-9));
}

TEST_CASE("NURBS arc length is exact to 1e-10 on evenly and very unevenly parametrized curves", "[nurbs]") {
  // A quarter circle as a rational quadratic with weights (1, k sqrt(2)/2, k^2): the same arc for every
  // k (the shape depends on w1^2 / (w0 w2) only), traversed ever more unevenly as k leaves 1, so the
  // quadrature's check fails and the spans are integrated adaptively.
  const double R = 3.0;
  for (double k : {1.0, 3.0, 30.0, 1000.0, 1e-3}) {
    const NurbsCurve arc(2, {0, 0, 0, 1, 1, 1}, {{R, 0, 0}, {R, R, 0}, {0, R, 0}}, {1.0, k * std::sqrt(0.5), k * k});
    CAPTURE(k);
    REQUIRE((arc.point(0.37) - Vec3::Zero()).norm() == Approx(R).epsilon(1e-12));
    CHECK(arc.arcLength() == Approx(0.5 * std::numbers::pi * R).epsilon(1e-10));
  }
  // The parabola y = x^2 for x in [-1, 2] as a quadratic Bezier: sum of x sqrt(1 + 4x^2) / 2 + asinh(2x) / 4.
  const NurbsCurve parabola(2, {0, 0, 0, 1, 1, 1}, {{-1, 1, 0}, {0.5, -2, 0}, {2, 4, 0}}, {1, 1, 1});
  const auto primitive = [](double x) { return 0.5 * x * std::sqrt(1 + 4 * x * x) + 0.25 * std::asinh(2 * x); };
  CHECK(parabola.arcLength() == Approx(primitive(2) - primitive(-1)).epsilon(1e-12));
  CHECK(parabola.arcLength(0.25, 0.75) == Approx(primitive(1.25) - primitive(-0.25)).epsilon(1e-12));
}

TEST_CASE("NURBS first and second derivatives match finite differences", "[nurbs]") {
  const NurbsCurve c = wigglyCubic();
  const double h = 1e-5;
  for (double u : {0.05, 0.2, 0.31, 0.5 + 1e-3, 0.65, 0.9, 0.97}) {
    Vec3 d[3], dp[3], dm[3];
    c.derivatives(u, 2, d);
    c.derivatives(u + h, 2, dp);
    c.derivatives(u - h, 2, dm);
    const Vec3 fd1 = (dp[0] - dm[0]) / (2 * h);
    const Vec3 fd2 = (dp[1] - dm[1]) / (2 * h);
    CAPTURE(u);
    REQUIRE((d[1] - fd1).norm() <= 1e-6 * (1 + d[1].norm()));
    REQUIRE((d[2] - fd2).norm() <= 1e-5 * (1 + d[2].norm()));
  }
  // The clamped curve interpolates its end control points.
  REQUIRE((c.point(0.0) - c.points().front()).norm() < 1e-14);
  REQUIRE((c.point(1.0) - c.points().back()).norm() < 1e-14);
}

TEST_CASE("B-spline basis functions form a partition of unity", "[nurbs]") {
  const std::vector<double> knots = {0, 0, 0, 0, 0.1, 0.4, 0.4, 0.7, 1, 1, 1, 1};
  const BSplineField ones(3, knots, std::vector<double>(8, 1.0));
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int k = 0; k < 500; ++k) {
    const double u = uni(rng);
    REQUIRE(ones.value(u) == Approx(1.0).epsilon(1e-14));
    REQUIRE(ones.derivative(u) == Approx(0.0).margin(1e-12));
    BasisDerivatives ders;
    const int span = findKnotSpan(knots, 3, 8, u);
    basisFunctionDerivatives(knots, 3, span, u, 0, ders);
    for (int j = 0; j <= 3; ++j) REQUIRE(ders[0][j] >= 0.0);
  }
  // A linear field with values at the Greville abscissae reproduces the identity exactly.
  std::vector<double> greville;
  for (int i = 0; i < 8; ++i) greville.push_back((knots[i + 1] + knots[i + 2] + knots[i + 3]) / 3.0);
  const BSplineField identity(3, knots, greville);
  for (double u : {0.0, 0.05, 0.33, 0.4, 0.77, 1.0}) {
    REQUIRE(identity.value(u) == Approx(u).margin(1e-14));
    REQUIRE(identity.derivative(u) == Approx(1.0).epsilon(1e-12));
  }
}

TEST_CASE("B-spline field bounds on an interval hold every value there, from the controls that act there", "[nurbs]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> value(-50, 200), where(0, 1);
  const BSplineField f(3, {0, 0, 0, 0, 0.2, 0.45, 0.7, 1, 1, 1, 1}, {10, -40, 150, 80, 5, 190, 30});
  for (int trial = 0; trial < 200; ++trial) {
    double a = where(rng), b = where(rng);
    if (a > b) std::swap(a, b);
    const auto [low, high] = f.valueBoundsOn(a, b);
    double seenLow = 1e300, seenHigh = -1e300;
    for (int k = 0; k <= 200; ++k) {
      const double v = f.value(a + (b - a) * k / 200.0);
      seenLow = std::min(seenLow, v);
      seenHigh = std::max(seenHigh, v);
    }
    CHECK(low <= seenLow);
    CHECK(high >= seenHigh);
  }
  // On [0.75, 0.95] only the last four controls act (the span [0.7, 1]).
  const auto [low, high] = f.valueBoundsOn(0.75, 0.95);
  CHECK(low == 5);
  CHECK(high == 190);
  CHECK(BSplineField::constant(42, 0, 1).valueBoundsOn(0.2, 0.3) == std::pair<double, double>(42, 42));
}

TEST_CASE("Closest point agrees with brute-force sampling", "[closest]") {
  const Rod rod("w", wigglyCubic(), Section::circle(0.5), std::nullopt, std::nullopt, CapStyle::Round,
                BSplineField::constant(10, 0, 1));
  std::vector<Vec3> dense;
  const int N = 200000;
  for (int k = 0; k <= N; ++k) dense.push_back(rod.centerline().point(static_cast<double>(k) / N));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(-2, 10), y(-3, 5), z(-3, 4);
  for (int k = 0; k < 300; ++k) {
    const Vec3 p(x(rng), y(rng), z(rng));
    double brute = 1e300;
    for (const Vec3& q : dense) brute = std::min(brute, (q - p).norm());
    const ClosestPoint c = rod.closestPoint(p);
    CAPTURE(p.transpose(), c.u);
    REQUIRE(c.distance <= brute + 1e-9);
    REQUIRE(c.distance >= brute - 1e-3);  // the dense sampling itself is only that fine
    REQUIRE((c.point - rod.centerline().point(c.u)).norm() < 1e-12);
  }
}

TEST_CASE("Closest point is exact for points equidistant from several spans", "[closest]") {
  const double R = 3.0;
  const Rod ring("ring", nurbsCircle(R), Section::circle(1.0), std::nullopt, std::nullopt, CapStyle::Round,
                 BSplineField::constant(10, 0, 1));
  // The centre is equidistant from every point of the circle; points on the axis too.
  for (double h : {0.0, 0.5, 2.0}) {
    const ClosestPoint c = ring.closestPoint(Vec3(0, 0, h));
    REQUIRE(c.distance == Approx(std::hypot(R, h)).epsilon(1e-12));
  }
  // Off-centre points: the exact answer is along the ray from the centre.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uni(-5, 5);
  for (int k = 0; k < 200; ++k) {
    const Vec3 p(uni(rng), uni(rng), uni(rng));
    const double rho = std::hypot(p.x(), p.y());
    if (rho < 1e-3) continue;
    const ClosestPoint c = ring.closestPoint(p);
    REQUIRE(c.distance == Approx(std::hypot(rho - R, p.z())).epsilon(1e-10));
  }
}

TEST_CASE("Rotation-minimizing frames are orthonormal and do not twist", "[frame]") {
  SECTION("planar curve: d1 seeded with the plane normal stays the plane normal") {
    const NurbsCurve c = wigglyCubic();
    // Flatten the wiggly curve into the xy-plane.
    std::vector<Vec3> pts = c.points();
    for (auto& p : pts) p.z() = 0;
    const NurbsCurve flat(3, c.knots(), pts, c.weights());
    const RodFrame f = RodFrame::rotationMinimizing(flat, Vec3(0, 0, 1));
    for (int k = 0; k <= 400; ++k) {
      const Frame fr = f.at(flat, k / 400.0);
      REQUIRE(std::abs(fr.d1.dot(Vec3(0, 0, 1))) == Approx(1.0).epsilon(1e-9));
      REQUIRE(fr.d1.dot(fr.d2) == Approx(0).margin(1e-12));
      REQUIRE(fr.d1.dot(fr.d3) == Approx(0).margin(1e-12));
      REQUIRE(fr.d2.dot(fr.d3) == Approx(0).margin(1e-12));
      REQUIRE(fr.d1.cross(fr.d2).dot(fr.d3) == Approx(1.0).epsilon(1e-12));
    }
  }
  SECTION("helix: the frame's angular velocity has no tangential component") {
    const NurbsCurve h = helix(2.0, 1.5, 3.0);
    const RodFrame f = RodFrame::rotationMinimizing(h, Vec3(1, 0, 0));
    const double du = 1e-6;
    for (int k = 1; k < 100; ++k) {
      const double u = k / 100.0;
      const Frame a = f.at(h, u - du), b = f.at(h, u + du);
      const Vec3 dd1 = (b.d1 - a.d1) / (2 * du);
      Vec3 d[3];
      h.derivatives(u, 1, d);
      // For an RMF, d1' is parallel to the tangent: twist rate d1' . d2 vanishes.
      const Frame m = f.at(h, u);
      REQUIRE(std::abs(dd1.dot(m.d2)) <= 1e-5 * d[1].norm());
    }
  }
}

TEST_CASE("Quaternion frames follow the spline's rotation", "[frame]") {
  // A straight rod along z whose section turns by 90 degrees about z from start to end.
  const NurbsCurve line(1, {0, 0, 1, 1}, {{0, 0, 0}, {0, 0, 10}});
  const double s = std::sqrt(0.5);
  QuaternionSpline q(1, {0, 0, 1, 1}, {{1, 0, 0, 0}, {s, 0, 0, s}});
  const RodFrame f = RodFrame::fromOrientation(line, q);
  const Frame start = f.at(line, 0.0), end = f.at(line, 1.0), mid = f.at(line, 0.5);
  REQUIRE((start.d1 - Vec3(1, 0, 0)).norm() < 1e-12);
  REQUIRE((end.d1 - Vec3(0, 1, 0)).norm() < 1e-12);
  // Normalized linear interpolation of the quaternion turns by 45 degrees at the midpoint.
  REQUIRE((mid.d1 - Vec3(s, s, 0)).norm() < 1e-12);
  REQUIRE((mid.d3 - Vec3(0, 0, 1)).norm() < 1e-12);
}

TEST_CASE("Sections: normalized radius, inside test, areas, perimeters", "[section]") {
  const Section e = Section::ellipse(4.0, 2.0);
  REQUIRE(e.normalizedRadius(2.0, 0.0) == Approx(1.0));
  REQUIRE(e.normalizedRadius(0.0, 1.0) == Approx(1.0));
  REQUIRE(e.contains(1.9, 0.0));
  REQUIRE_FALSE(e.contains(1.5, 0.8));
  const Section r = Section::rectangle(4.0, 2.0);
  REQUIRE(r.contains(1.9, 0.9));
  REQUIRE_FALSE(r.contains(2.1, 0.0));
  REQUIRE(r.boundingRadius() == Approx(std::sqrt(5.0)));
  REQUIRE(r.capRadius() == Approx(1.0));
  REQUIRE(Section::circle(2.0).area() == Approx(std::numbers::pi));
  REQUIRE(e.area() == Approx(2.0 * std::numbers::pi));
  REQUIRE(Section::circle(2.0).perimeter() == Approx(2.0 * std::numbers::pi).epsilon(1e-12));
  REQUIRE(r.perimeter() == Approx(12.0));
  // Ellipses against the arc length summed over 200,000 chords, from round to 1000:1 flat.
  for (const double h : {2.0, 1.0, 0.1, 0.004}) {
    const Section flat = Section::ellipse(4.0, h);
    double chords = 0.0;
    constexpr int kSteps = 200000;
    for (int i = 0; i < kSteps; ++i) {
      const double t0 = 2 * std::numbers::pi * i / kSteps, t1 = 2 * std::numbers::pi * (i + 1) / kSteps;
      chords += std::hypot(2.0 * (std::cos(t1) - std::cos(t0)), 0.5 * h * (std::sin(t1) - std::sin(t0)));
    }
    CAPTURE(h);
    REQUIRE(flat.perimeter() == Approx(chords).epsilon(5e-4));
  }
}

TEST_CASE("Rod inside test covers the swept section and the caps", "[rod]") {
  const NurbsCurve line(1, {0, 0, 1, 1}, {{0, 0, 0}, {10, 0, 0}});
  const auto rod = [&](CapStyle caps) {
    return Rod("r", line, Section::rectangle(2.0, 1.0), Vec3(0, 1, 0), std::nullopt, caps, BSplineField::constant(5, 0, 1));
  };
  const Rod round = rod(CapStyle::Round), flat = rod(CapStyle::Flat);
  // d1 = y (width 2), d2 = z (height 1).
  REQUIRE(round.classify(Vec3(5, 0.99, 0)).inside);
  REQUIRE_FALSE(round.classify(Vec3(5, 0, 0.51)).inside);
  REQUIRE(round.classify(Vec3(5, 0, 0)).depth == Approx(1.0));
  // Round cap: half-ball of radius 0.5 beyond x = 10.
  REQUIRE(round.classify(Vec3(10.45, 0, 0)).inside);
  REQUIRE_FALSE(round.classify(Vec3(10.55, 0, 0)).inside);
  REQUIRE_FALSE(flat.classify(Vec3(10.05, 0, 0)).inside);
  REQUIRE(flat.classify(Vec3(9.95, 0.9, 0.4)).inside);
  // Bounds: exact for a straight rod.
  const Box3 b = round.bounds();
  REQUIRE(b.min().x() == Approx(-0.5).margin(1e-6));
  REQUIRE(b.max().x() == Approx(10.5).margin(1e-6));
  REQUIRE(b.max().y() == Approx(1.0).margin(1e-6));
  REQUIRE(b.max().z() == Approx(0.5).margin(1e-6));
  REQUIRE(flat.bounds().max().x() == Approx(10.0).margin(1e-6));
}

TEST_CASE("Bounds of a torus-like ring contain every sampled surface point", "[rod]") {
  const Rod ring("ring", nurbsCircle(5.0), Section::circle(2.0), std::nullopt, std::nullopt, CapStyle::Round,
                 BSplineField::constant(10, 0, 1));
  const Box3 b = ring.bounds();
  REQUIRE(b.max().x() == Approx(6.0).margin(1e-3));
  REQUIRE(b.max().x() >= 6.0);
  REQUIRE(b.max().z() == Approx(1.0).margin(1e-3));
  REQUIRE(ring.length() == Approx(10 * std::numbers::pi).epsilon(1e-9));
}

// ---- Kinks and scale-safe numerics ----

namespace {

NurbsCurve bentPolyline() { return NurbsCurve(1, {0, 0, 0.5, 1, 1}, {{0, 0, 0}, {3, 0, 0}, {3, 3, 0}}); }

Rod rodOf(NurbsCurve c, double diameter, CapStyle caps) {
  return Rod("bent", std::move(c), Section::circle(diameter), std::nullopt, std::nullopt, caps, BSplineField::constant(5, 0, 1));
}

// The error message of a design that must fail to parse.
std::string designError(const std::string& text) {
  try {
    parseDesign(text, "d.json");
  } catch (const DesignError& e) {
    return e.what();
  }
  return "(no error)";
}

std::string oneRod(const std::string& centerline, const std::string& extra = "") {
  return R"({"format": "rodfab.design/1", "units": "mm", "rods": [{"name": "r", "centerline": )" + centerline +
         R"(, "section": {"shape": "rectangle", "width": 1, "height": 0.5}, "modulus": 10)" + extra + "}]}";
}
const char* kLine = R"({"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, 0], [2, 0, 0]]})";

}  // namespace

TEST_CASE("Derivatives from below a kink are those of the span ending there", "[nurbs][kink]") {
  const NurbsCurve c = bentPolyline();
  Vec3 below[3], above[3];
  c.derivativesFromBelow(0.5, 1, below);
  c.derivatives(0.5, 1, above);
  REQUIRE((below[0] - Vec3(3, 0, 0)).norm() < 1e-15);
  REQUIRE((above[0] - Vec3(3, 0, 0)).norm() < 1e-15);
  REQUIRE((below[1] - Vec3(6, 0, 0)).norm() < 1e-12);  // (3, 0, 0) over half the parameter range
  REQUIRE((above[1] - Vec3(0, 6, 0)).norm() < 1e-12);
  // Away from knots, and at the domain's ends, both agree.
  for (const double u : {0.0, 0.2, 0.7, 1.0}) {
    c.derivativesFromBelow(u, 1, below);
    c.derivatives(u, 1, above);
    REQUIRE((below[1] - above[1]).norm() < 1e-12);
  }
  // A fold back: r' vanishes and the curve arrives along -r''.
  REQUIRE((unitTangentFromBelow(Vec3::Zero(), Vec3(0, 0, 2)) - Vec3(0, 0, -1)).norm() < 1e-15);
}

TEST_CASE("C0 points split a rod into smooth pieces, the joint follows the caps", "[rod][kink]") {
  const Rod round = rodOf(bentPolyline(), 1.0, CapStyle::Round), flat = rodOf(bentPolyline(), 1.0, CapStyle::Flat);
  REQUIRE(round.smoothPieces().size() == 2);
  const SmoothPiece& first = round.smoothPieces()[0];
  REQUIRE(first.begin == 0.0);
  REQUIRE(first.end == 0.5);
  REQUIRE(first.endFromBelow);
  REQUIRE((first.endTangent - Vec3(1, 0, 0)).norm() < 1e-12);
  REQUIRE((round.smoothPieces()[1].beginTangent - Vec3(0, 1, 0)).norm() < 1e-12);
  REQUIRE(round.sampleParameters()[first.lastSample] == 0.5);
  REQUIRE(rodOf(wigglyCubic(), 0.5, CapStyle::Round).smoothPieces().size() == 1);

  // The outer corner: (3.3, -0.3) is 0.42 from the vertex, beyond both end planes. Projected onto the
  // plane of either piece it lies within the radius, which the old rule took for inside.
  REQUIRE(round.classify(Vec3(3.3, -0.3, 0)).inside);
  REQUIRE(round.classify(Vec3(3.3, -0.3, 0)).depth == Approx(1 - std::hypot(0.3, 0.3) / 0.5));
  REQUIRE_FALSE(round.classify(Vec3(3.4, -0.4, 0)).inside);
  REQUIRE_FALSE(flat.classify(Vec3(3.3, -0.3, 0)).inside);
  REQUIRE_FALSE(flat.classify(Vec3(3.05, -0.45, 0.2)).inside);  // 0.5 from the vertex, beyond the first piece's end
  REQUIRE(flat.classify(Vec3(2.9, -0.45, 0.2)).inside);        // in the first piece's section
  REQUIRE(flat.classify(Vec3(3.45, 0.1, 0.2)).inside);         // in the second's
  // The inner corner belongs to both pieces: the deeper one gives the depth.
  const RodHit inner = flat.classify(Vec3(2.8, 0.3, 0));
  REQUIRE(inner.depth == Approx(1 - 0.2 / 0.5));
  REQUIRE(inner.u == Approx(0.5 + 0.3 / 6.0));  // the second piece: 0.2 from its axis, the first 0.3

  // Bounds hold the ball joint but not the bare corner of flat pieces.
  REQUIRE(round.bounds().min().y() == Approx(-0.5).margin(1e-6));
  REQUIRE(round.bounds().max().x() == Approx(3.5).margin(1e-6));
  REQUIRE(flat.bounds().min().y() == Approx(-0.5).margin(1e-6));  // the first piece's section at its end
  REQUIRE(flat.bounds().max().z() == Approx(0.5).margin(1e-6));
}

TEST_CASE("Bounds contain every point the inside test accepts, on kinked and folded rods", "[rod][kink]") {
  const std::vector<Rod> rods = {
      rodOf(NurbsCurve(1, {0, 0, 0.25, 0.5, 0.75, 1, 1}, {{0, 0, 0}, {2, 0, 0}, {2.3, 1, 0.2}, {0.5, 1.5, -0.5}, {0.5, 0.2, 1}}), 0.6,
            CapStyle::Round),
      Rod("rect", NurbsCurve(2, {0, 0, 0, 0.5, 0.5, 1, 1, 1}, {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 1, 0.5}, {1, 2, 1}}),
          Section::rectangle(0.9, 0.3), Vec3(0, 0, 1), std::nullopt, CapStyle::Flat, BSplineField::constant(5, 0, 1)),
      rodOf(NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1, 1}, {{0, 0, 0}, {1, 0, 0}, {2, 1, 0}, {3, 1, 0}}, {1, 1e4, 1e4, 1}), 2.5,
            CapStyle::Round),
  };
  std::mt19937 rng(11);
  for (const Rod& rod : rods) {
    const Box3 b = rod.bounds();
    const Box3 search(b.min() - Vec3::Constant(0.3), b.max() + Vec3::Constant(0.3));
    std::uniform_real_distribution<double> x(search.min().x(), search.max().x()), y(search.min().y(), search.max().y()),
        z(search.min().z(), search.max().z());
    int inside = 0;
    for (int n = 0; n < 60000; ++n) {
      const Vec3 p(x(rng), y(rng), z(rng));
      if (!rod.classify(p).inside) continue;
      ++inside;
      REQUIRE(b.contains(p));
    }
    REQUIRE(inside > 3000);
  }
}

TEST_CASE("Quaternions and normals of any finite magnitude give the same frames", "[frame][numerics]") {
  const double s45 = std::sqrt(0.5);
  const std::vector<Eigen::Vector4d> unit = {{1, 0, 0, 0}, {s45, 0, s45, 0}};
  for (const double scale : {1e160, 1e300, 1e-150, 3.0}) {
    const QuaternionSpline a(1, {0, 0, 1, 1}, unit), b(1, {0, 0, 1, 1}, {unit[0] * scale, unit[1] * scale});
    for (const double u : {0.0, 0.3, 1.0}) REQUIRE(a.rotation(u).angularDistance(b.rotation(u)) < 1e-12);
    REQUIRE(b.rotation(1.0).angularDistance(Eigen::Quaterniond::Identity()) == Approx(0.5 * std::numbers::pi));
  }
  REQUIRE_THROWS_AS(QuaternionSpline(1, {0, 0, 1, 1}, {{0, 0, 0, 0}, {1, 0, 0, 0}}), std::invalid_argument);

  const NurbsCurve c = wigglyCubic();
  const RodFrame reference = RodFrame::rotationMinimizing(c, Vec3(0, 0, 1));
  for (const double scale : {1e300, 1e-300}) {
    const RodFrame scaled = RodFrame::rotationMinimizing(c, Vec3(0, 0, scale));
    for (const double u : {0.0, 0.5, 1.0}) REQUIRE((scaled.at(c, u).d1 - reference.at(c, u).d1).norm() < 1e-14);
  }
  REQUIRE(stableNorm(Vec3(3e200, 4e200, 0)) == Approx(5e200));
  REQUIRE(stableNorm(Vec3(3e-200, 4e-200, 0)) == Approx(5e-200));
}

TEST_CASE("The design reader names huge coordinates, huge normals and tiny quaternions correctly", "[design][numerics]") {
  const std::string huge = designError(oneRod(R"({"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, 0], [1e300, 0, 0]]})",
                                              R"(, "normal": [0, 0, 1])"));
  REQUIRE_THAT(huge, Catch::Contains("rods[0].centerline.points[1]") && Catch::Contains("within +-1e9 mm"));
  REQUIRE_THAT(huge, !Catch::Contains("length is zero"));
  REQUIRE_NOTHROW(parseDesign(oneRod(R"({"degree": 1, "knots": [0, 0, 1, 1], "points": [[0, 0, 0], [9e8, 0, 0]]})",
                                     R"(, "normal": [0, 0, 1])"),
                              "d.json"));
  // A normal of 1e300 is a direction like any other, not "parallel to the tangent"; zero is zero.
  const RodStructure s = parseDesign(oneRod(kLine, R"(, "normal": [0, 0, 1e300])"), "d.json");
  REQUIRE((s.rods[0].frame().at(s.rods[0].centerline(), 0.5).d1 - Vec3(0, 0, 1)).norm() < 1e-12);
  REQUIRE_NOTHROW(parseDesign(oneRod(kLine, R"(, "normal": [0, 1e-300, 1e-300])"), "d.json"));
  REQUIRE_THAT(designError(oneRod(kLine, R"(, "normal": [1e300, 0, 0])")), Catch::Contains("parallel to the centerline"));
  REQUIRE_THAT(designError(oneRod(kLine, R"(, "normal": [0, 0, 0])")), Catch::Contains("must not be zero"));
  // Quaternions of 1e160 rotate like unit ones (they used to turn into the identity); 1e-170 is not zero.
  const std::string q = R"(, "orientation": {"degree": 1, "knots": [0, 0, 1, 1], "quaternions": [[SCALE, 0, 0, 0], [0, SCALE, 0, 0]]})";
  for (const std::string scale : {"1e160", "1e-170", "1"}) {
    std::string extra = q;
    for (std::size_t at; (at = extra.find("SCALE")) != std::string::npos;) extra.replace(at, 5, scale);
    const RodStructure d = parseDesign(oneRod(kLine, extra), "d.json");
    // 180 degrees about x at the end: d1 (x before) stays x, d2 flips.
    const Frame f = d.rods[0].frame().at(d.rods[0].centerline(), 1.0);
    INFO(scale);
    REQUIRE((f.d2 - Vec3(0, -1, 0)).norm() < 1e-9);
  }
  REQUIRE_THAT(designError(oneRod(kLine, R"(, "orientation": {"degree": 1, "knots": [0, 0, 1, 1], "quaternions": [[0, 0, 0, 0], [1, 0, 0, 0]]})")),
               Catch::Contains("zero quaternion"));
}
