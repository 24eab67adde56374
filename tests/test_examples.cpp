// examples/: the bundled designs are what the generator makes, and they are sound structures.
#include "examples/example_designs.hpp"
#include "geometry/geometry.hpp"
#include "mechanics/mechanics.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <numbers>
#include <numeric>

using namespace rodfab;
using geometry::Vec3;

namespace {

// Rods touch when an end of one lies on the other's centerline: union them and count components.
std::size_t connectedComponents(const geometry::RodStructure& s, double tolerance) {
  std::vector<std::size_t> parent(s.rods.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](std::size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (std::size_t a = 0; a < s.rods.size(); ++a) {
    const auto& ca = s.rods[a].centerline();
    for (const Vec3& end : {ca.point(ca.domainBegin()), ca.point(ca.domainEnd())}) {
      for (std::size_t b = 0; b < s.rods.size(); ++b) {
        if (b == a || s.rods[b].bounds().exteriorDistance(end) > tolerance) continue;
        if (s.rods[b].closestPoint(end).distance < tolerance) parent[find(a)] = find(b);
      }
    }
  }
  std::size_t roots = 0;
  for (std::size_t i = 0; i < parent.size(); ++i) roots += find(i) == i;
  return roots;
}

void requireMatchesCommittedFile(const mechanics::Design& generated, const std::string& file) {
  const mechanics::Design committed = mechanics::readDesign(std::string(RODFAB_SOURCE_DIR "/examples/") + file);
  INFO(file << ": regenerate with rodfab_generate_examples");
  REQUIRE(mechanics::designToJson(committed) == mechanics::designToJson(generated));
}

}  // namespace

TEST_CASE("Unfolding box: 34 rods, flat, one connected net", "[examples]") {
  mechanics::Design box(examples::unfoldingBox());
  box.mechanics = examples::unfoldingBoxTraining();
  requireMatchesCommittedFile(box, "unfolding-box.json");
  REQUIRE(box.rods.size() == 34);
  const auto summary = geometry::summarize(box);
  REQUIRE(summary.bounds.sizes().z() == Approx(1.5).margin(1e-6));  // printed flat: one rod thick
  REQUIRE(summary.ellipses == 10);
  REQUIRE(summary.modulusMin == Approx(8.0));
  REQUIRE(summary.modulusMax == Approx(120.0));
  // Six 20 mm squares: 24 edges of 20 mm, 10 hinges of 2.5 mm.
  REQUIRE(summary.totalLength == Approx(24 * 20.0 + 10 * 2.5).epsilon(1e-9));
  REQUIRE(connectedComponents(box, 1e-9) == 1);
}

TEST_CASE("Buckling spring: 312 rods on the cylinder, softest at mid-height", "[examples]") {
  const examples::SpringParameters p;
  mechanics::Design spring(examples::bucklingSpring(p));
  spring.mechanics = examples::bucklingSpringTraining(p);
  requireMatchesCommittedFile(spring, "buckling-spring.json");
  REQUIRE(spring.rods.size() == 312);
  REQUIRE(connectedComponents(spring, 1e-9) == 1);
  for (const auto& rod : spring.rods) {
    const auto& c = rod.centerline();
    for (int k = 0; k <= 10; ++k) {
      const Vec3 q = c.point(k / 10.0);
      // Struts interpolate the helix at four points: they stay within 0.05 mm of the cylinder.
      REQUIRE(std::hypot(q.x(), q.y()) == Approx(p.radius).margin(0.05));
      const double t = std::abs(q.z() / p.height - 0.5) * 2.0;
      const double expected = p.modulusMiddle + (p.modulusEnds - p.modulusMiddle) * t * t;
      // E is piecewise linear along each strut: close to the quadratic profile in z.
      REQUIRE(rod.modulus().value(k / 10.0) == Approx(expected).margin(0.03 * p.modulusEnds));
    }
  }
  const auto summary = geometry::summarize(spring);
  REQUIRE(summary.modulusMin == Approx(p.modulusMiddle));
  REQUIRE(summary.bounds.sizes().z() == Approx(p.height + p.rodDiameter).margin(1e-3));
}

TEST_CASE("Scaled buckling spring fills the 6-gigavoxel envelope", "[examples]") {
  const Vec3 envelope(84.6, 84.6, 90.0);
  const auto spring = examples::bucklingSpringScaledTo(envelope, 1.2);
  REQUIRE(spring.rods.size() == 312);
  const Vec3 size = spring.bounds().sizes();
  REQUIRE((size.array() <= envelope.array() + 1e-6).all());
  // Limited by one dimension, and the design fills it.
  REQUIRE(std::max({size.x() / envelope.x(), size.z() / envelope.z()}) == Approx(1.0).margin(2e-3));
}

TEST_CASE("Arm cast: rectangular strips on a half cylinder, surface-normal frames", "[examples]") {
  mechanics::Design cast(examples::armCast());
  cast.mechanics = examples::armCastTraining();
  requireMatchesCommittedFile(cast, "arm-cast.json");
  REQUIRE(cast.rods.size() > 150);
  REQUIRE(connectedComponents(cast, 1e-9) == 1);
  const auto summary = geometry::summarize(cast);
  REQUIRE(summary.rectangles == cast.rods.size());
  for (const auto& rod : cast.rods) {
    const auto& c = rod.centerline();
    for (double u : {0.0, 0.5, 1.0}) {
      const Vec3 q = c.point(u);
      REQUIRE(std::hypot(q.y(), q.z()) == Approx(30.0).margin(0.05));
      REQUIRE(q.z() >= -1e-9);
      // d1 (the 1 mm thickness) stays along the surface normal.
      const auto f = rod.frame().at(c, u);
      const Vec3 radial = Vec3(0, q.y(), q.z()).normalized();
      REQUIRE(std::abs(f.d1.dot(radial)) == Approx(1.0).margin(2e-3));
    }
  }
}

// ---- Training cases: `rodfab simulate` on the committed files converges, to the trained shapes ----

namespace {

struct Trained {
  mechanics::Design design;
  mechanics::Simulation sim;
  Vec3 at(std::size_t rod, double u) const { return sim.problem->position(sim.solution.state, rod, u); }
  std::size_t rod(const std::string& name) const {
    for (std::size_t i = 0; i < design.rods.size(); ++i)
      if (design.rods[i].name() == name) return i;
    FAIL("no rod " << name);
    return 0;
  }
};

// Simulated as `rodfab simulate FILE` does with its defaults.
Trained trained(const std::string& file) {
  Trained t{mechanics::readDesign(std::string(RODFAB_SOURCE_DIR "/examples/") + file), {}};
  REQUIRE(t.design.mechanics.present);
  t.sim = mechanics::simulate(t.design, {}, {}, t.design.mechanics.loadSteps);
  REQUIRE(t.sim.solution.steps.back().loadFactor == 1.0);
  REQUIRE(t.sim.estimate.available);
  INFO(file << ": estimated relative error " << t.sim.estimate.relative);
  CHECK(t.sim.estimate.relative < 1e-4);
  return t;
}

}  // namespace

TEST_CASE("Unfolding box training: the outer squares fold up about their T-jointed hinges", "[examples][mechanics]") {
  const Trained t = trained("unfolding-box.json");
  CHECK(t.sim.problem->jointCount() == 4 * 6 + 20);  // square corners, and each hinge end on an edge
  // The middle square stays; every outer square's outer edge rises to about the side length.
  CHECK((t.at(t.rod("square11-edge0"), 0.5) - Vec3(32.5, 22.5, 0)).norm() < 0.1);
  for (const char* edge : {"square10-edge0", "square01-edge3", "square21-edge1"}) {
    const Vec3 middle = t.at(t.rod(edge), 0.5);
    INFO(edge << " middle at " << middle.transpose());
    CHECK(middle.z() > 15.0);
    CHECK(middle.z() < 22.5);
  }
  // The lid, two hinges from the base, ends above the box's side walls.
  CHECK(t.at(t.rod("square13-edge2"), 0.5).z() > 22.5);
}

TEST_CASE("Buckling spring training: compressed at four points of its top, it bulges at mid-height", "[examples][mechanics]") {
  const examples::SpringParameters p;
  const Trained t = trained("buckling-spring.json");
  const double drop = 0.15 * p.height;
  CHECK(t.sim.estimate.largestDisplacement == Approx(drop).epsilon(0.01));
  // Radial bulge of the struts' middles near the ends and at mid-height.
  double ends = 0, middle = 0;
  for (std::size_t r = 0; r < t.design.rods.size(); ++r) {
    if (t.design.rods[r].name().rfind("strut-", 0) != 0) continue;
    const Vec3 before = t.design.rods[r].centerline().point(0.5), after = t.at(r, 0.5);
    const double bulge = std::hypot(after.x(), after.y()) - std::hypot(before.x(), before.y());
    if (std::abs(before.z() - 0.5 * p.height) < 0.1 * p.height) middle = std::max(middle, bulge);
    else if (std::abs(before.z() - 0.5 * p.height) > 0.4 * p.height) ends = std::max(ends, std::abs(bulge));
  }
  INFO("largest bulge at mid-height " << middle << " mm, near the ends " << ends << " mm");
  CHECK(middle > 0.25 * drop);
  CHECK(middle > 4 * ends);
}

TEST_CASE("Arm cast training: the half cylinder is flattened", "[examples][mechanics]") {
  const Trained t = trained("arm-cast.json");
  // Drawn on a half cylinder of radius 30 (z from 0 to 30); flattened onto the plane z = 30 over
  // the full unrolled width (y = +-30 pi / 2).
  double zMin = 1e9, zMax = -1e9, yMax = 0;
  for (std::size_t r = 0; r < t.design.rods.size(); ++r)
    for (double u : {0.0, 0.25, 0.5, 0.75, 1.0}) {
      const Vec3 q = t.at(r, u);
      zMin = std::min(zMin, q.z()), zMax = std::max(zMax, q.z()), yMax = std::max(yMax, std::abs(q.y()));
    }
  INFO("z from " << zMin << " to " << zMax << ", |y| up to " << yMax);
  CHECK(zMax - zMin < 6.0);
  CHECK(yMax == Approx(30.0 * std::numbers::pi / 2).margin(0.05));
}
