// Rotation-minimizing frames against an independent solution: the RMF's defining equation
// d1' = -(d1 . t') t integrated by classical Runge-Kutta at a step far finer than the frame's samples.
#include "geometry/frame.hpp"
#include "tests/test_geometry_curves.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

using namespace rodfab::geometry;
using rodfab::geometry::testing::helix;

namespace {

// t and dt/du at u.
void tangentAndRate(const NurbsCurve& c, double u, Vec3& t, Vec3& rate) {
  Vec3 d[3];
  c.derivatives(u, 2, d);
  const double speed = d[1].norm();
  t = d[1] / speed;
  rate = (d[2] - d[2].dot(t) * t) / speed;
}

Vec3 rmfRate(const NurbsCurve& c, double u, const Vec3& d1) {
  Vec3 t, rate;
  tangentAndRate(c, u, t, rate);
  return -d1.dot(rate) * t;
}

// The largest angle (rad) between the frame's d1 and the integrated RMF's, integrated from the frame's
// own d1 at the curve's start in `steps` RK4 steps a knot span (steps within a span, where the curve
// is smooth, keep RK4's fourth order: uniform steps across the knots converged to 1e-8 rad only), and
// compared at 16 points a span.
double largestAngleToIntegrated(const NurbsCurve& c, const RodFrame& frame, int steps) {
  const std::vector<double> bp = c.breakpoints();
  Vec3 d1 = frame.at(c, bp.front()).d1;
  double largest = 0.0;
  for (std::size_t span = 0; span + 1 < bp.size(); ++span) {
    const double h = (bp[span + 1] - bp[span]) / steps;
    for (int s = 0; s < steps; ++s) {
      const double u = bp[span] + h * s;
      if (s % (steps / 16) == 0) {
        Vec3 t, rate;
        tangentAndRate(c, u, t, rate);
        const Vec3 reference = (d1 - d1.dot(t) * t).normalized();
        const Vec3 d1Frame = frame.at(c, u).d1;  // the angle by atan2: acos near 1 loses half the digits
        largest = std::max(largest, std::atan2(reference.cross(d1Frame).norm(), reference.dot(d1Frame)));
      }
      const Vec3 k1 = rmfRate(c, u, d1), k2 = rmfRate(c, u + h / 2, d1 + h / 2 * k1);
      const Vec3 k3 = rmfRate(c, u + h / 2, d1 + h / 2 * k2), k4 = rmfRate(c, u + h, d1 + h * k3);
      d1 += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    }
  }
  return largest;
}

// A cubic of `spans` uniform spans on a gently bent, twisting path `length` long (its bend radius
// about 1.3 times its length), like a mesh-made rod's.
NurbsCurve gentleRod(int spans, double length) {
  std::vector<Vec3> pts;
  for (int i = 0; i < spans + 3; ++i) {
    const double a = double(i) / (spans + 2);
    pts.emplace_back(length * a, 0.1 * length * std::sin(3.0 * a), 0.05 * length * (1.0 - std::cos(2.0 * a)));
  }
  std::vector<double> knots(4, 0.0);
  for (int i = 1; i < spans; ++i) knots.push_back(double(i) / spans);
  knots.insert(knots.end(), 4, 1.0);
  return NurbsCurve(3, knots, pts);
}

// A cubic of `spans` uniform spans through points jittered by up to 5 % of `length` about a line.
NurbsCurve jitteredRod(int spans, double length, std::mt19937& rng) {
  std::uniform_real_distribution<double> jitter(-0.05 * length, 0.05 * length);
  std::vector<Vec3> pts;
  for (int i = 0; i < spans + 3; ++i) pts.emplace_back(length * i / (spans + 2), jitter(rng), jitter(rng));
  std::vector<double> knots(4, 0.0);
  for (int i = 1; i < spans; ++i) knots.push_back(double(i) / spans);
  knots.insert(knots.end(), 4, 1.0);
  return NurbsCurve(3, knots, pts);
}

}  // namespace

TEST_CASE("Rotation-minimizing frames match the integrated RMF within their estimate", "[frame]") {
  struct Case {
    const char* name;
    NurbsCurve curve;
  };
  std::mt19937 rng(11);
  const std::vector<Case> cases{
      {"helix, 3 turns", helix(2.0, 1.5, 3.0)},
      {"steep helix, 8 points a turn", helix(1.0, 4.0, 2.0, 8)},
      {"rational wiggly cubic", NurbsCurve(3, {0, 0, 0, 0, 0.3, 0.5, 0.8, 1, 1, 1, 1},
                                           {{0, 0, 0}, {1, 2, 0}, {3, -1, 1}, {4, 2, 2}, {6, 0, 1}, {7, 1, -1}, {8, 3, 0}},
                                           {1, 0.7, 1.3, 1, 2, 0.8, 1})},
      {"1.5 mm gently bent rod", gentleRod(5, 1.5)},
      {"40 mm jittered rod", jitteredRod(12, 40.0, rng)},
  };
  for (const Case& c : cases) {
    INFO(c.name);
    const RodFrame frame = RodFrame::rotationMinimizing(c.curve, Vec3(0, 0, 1).cross(Vec3(1, 2, 3)));
    const double error = largestAngleToIntegrated(c.curve, frame, 1600);
    INFO("error " << error << " rad, estimated " << frame.estimatedError() << ", samples " << frame.sampleCount());
    // The estimate is the error within a few per cent (the integration's own error is ~1e-14 rad),
    // also where the samples' limit stopped the doubling short of the tolerance (the steep helix).
    CHECK(error <= 1.1 * frame.estimatedError() + 1e-13);
    CHECK(error >= 0.9 * frame.estimatedError() - 1e-13);
    const std::size_t spans = c.curve.breakpoints().size() - 1;
    if (frame.sampleCount() < std::size_t(kMaxSamplesPerSpan) * spans + 1)
      CHECK(frame.estimatedError() <= kFrameTolerance * 16.0 / 15.0);
    else
      CHECK(frame.estimatedError() < 1e-8);
  }
}

TEST_CASE("Rotation-minimizing frames keep few samples where few suffice", "[frame]") {
  const auto spansOf = [](const NurbsCurve& c) { return c.breakpoints().size() - 1; };
  // A planar bent rod (the curved lattice's): the frame is exact at any spacing, four samples a span.
  std::vector<Vec3> arcPoints;
  for (int i = 0; i < 8; ++i) arcPoints.emplace_back(i, 0.3 * std::sin(0.5 * i), 0.0);
  const NurbsCurve planar(3, {0, 0, 0, 0, 0.2, 0.4, 0.6, 0.8, 1, 1, 1, 1}, arcPoints);
  const RodFrame planarFrame = RodFrame::rotationMinimizing(planar, Vec3(1, 1, 1));
  CHECK(planarFrame.sampleCount() == 4 * spansOf(planar) + 1);
  CHECK(planarFrame.estimatedError() <= 1e-14);
  // A gently bent and twisting 1.5 mm rod (a mesh-made one): between that and 64 a span.
  const NurbsCurve shortRod = gentleRod(5, 1.5);
  const RodFrame shortFrame = RodFrame::rotationMinimizing(shortRod, Vec3(0, 0, 1));
  CHECK(shortFrame.sampleCount() > 4 * spansOf(shortRod) + 1);
  CHECK(shortFrame.sampleCount() < 64 * spansOf(shortRod) + 1);
  // A straight line: the frame is exact at any spacing.
  const NurbsCurve line(1, {0, 0, 1, 1}, {{0, 0, 0}, {3, 4, 5}});
  const RodFrame straight = RodFrame::rotationMinimizing(line, Vec3(0, 0, 1));
  CHECK(straight.sampleCount() == 5);
  CHECK(straight.estimatedError() <= 1e-15);
  // A steep helix of few control points a turn needs more than the limit: it stops there, its estimate
  // above the tolerance.
  const NurbsCurve steep = helix(1.0, 4.0, 2.0, 8);
  const RodFrame steepFrame = RodFrame::rotationMinimizing(steep, Vec3(0, 0, 1));
  CHECK(steepFrame.sampleCount() == kMaxSamplesPerSpan * spansOf(steep) + 1);
  CHECK(steepFrame.estimatedError() > kFrameTolerance);
}

TEST_CASE("Rotation-minimizing frames of curves with very many spans stay within the sample budget", "[frame]") {
  // 40,000 spans of a coil: four samples a span (more than kMaxFrameSamples in all), and the estimate
  // says how far that is from converged.
  const NurbsCurve coil = helix(1.0, 0.5, 2500.0, 16);
  const RodFrame frame = RodFrame::rotationMinimizing(coil, Vec3(0, 0, 1));
  CHECK(frame.sampleCount() == 4 * (coil.breakpoints().size() - 1) + 1);
  CHECK(frame.estimatedError() > kFrameTolerance);
  CHECK(std::isfinite(frame.estimatedError()));
}
