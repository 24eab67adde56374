// examples/: the bundled designs are what the generator makes, and they are sound structures.
#include "examples/example_designs.hpp"
#include "geometry/geometry.hpp"
#include "mechanics/mechanics.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <filesystem>
#include <map>
#include <numbers>
#include <numeric>
#include <string>
#include <tuple>

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
  box.mechanics.loadCases = {examples::unfoldingBoxFold()};
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
  spring.mechanics.loadCases = {examples::bucklingSpringCompression(p)};
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
  cast.mechanics.loadCases = {examples::armCastFlattened()};
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
  // The lid, two hinges from the base, is carried up by the back wall and, its force turning with
  // it, folds over towards the box: its outer edge high and past the back wall's top (in y).
  const Vec3 lidEdge = t.at(t.rod("square13-edge2"), 0.5), backTop = t.at(t.rod("square12-edge2"), 0.5);
  INFO("lid's outer edge at " << lidEdge.transpose() << ", back wall's top at " << backTop.transpose());
  CHECK(backTop.z() > 5.0);
  CHECK(lidEdge.z() > 15.0);
  CHECK(lidEdge.y() < backTop.y() - 10.0);
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

// ---- Training targets: geometric facts of the published target shapes, checked on the targets.

namespace {

double lengthOf(const geometry::RodStructure& s, const std::string& name) {
  for (const geometry::Rod& r : s.rods)
    if (r.name() == name) return r.centerline().arcLength();
  FAIL("no rod " << name);
  return 0;
}

}  // namespace

TEST_CASE("Unfolding box target: a closed box, squares rigid, hinges bent to quarter circles of their length", "[examples]") {
  const geometry::RodStructure box = examples::unfoldingBox();
  const mechanics::LoadCase fold = examples::unfoldingBoxFold();
  REQUIRE(fold.target.size() == box.rods.size());
  REQUIRE(fold.supports.size() == 4);
  REQUIRE(fold.loads.size() == 4);
  const double radius = 2 * 2.5 / std::numbers::pi;  // a 2.5 mm hinge bent through 90 degrees
  Eigen::AlignedBox3d bounds;
  for (const mechanics::TargetRod& t : fold.target) {
    INFO(t.rod);
    CHECK(t.centerline.arcLength() == Approx(lengthOf(box, t.rod)).epsilon(2e-3));  // an isometry
    for (double u : {0.0, 0.3, 0.7, 1.0}) bounds.extend(t.centerline.point(u));
    if (t.rod.rfind("square13", 0) == 0)  // the lid, on top: turned through 180 degrees
      for (double u : {0.0, 0.5, 1.0}) CHECK(t.centerline.point(u).z() == Approx(20 + 2 * radius).margin(1e-9));
    if (t.rod.rfind("square11", 0) == 0)  // the middle square stays
      for (const geometry::Rod& r : box.rods)
        if (r.name() == t.rod) CHECK((t.centerline.point(0.5) - r.centerline().point(0.5)).norm() < 1e-12);
  }
  // A cube of side 20 + 2 r around the middle square [22.5, 42.5]^2 (hinges slightly outside).
  CHECK(bounds.min().x() == Approx(22.5 - radius).margin(0.05));
  CHECK(bounds.max().x() == Approx(42.5 + radius).margin(0.05));
  CHECK(bounds.min().y() == Approx(22.5 - radius).margin(0.05));
  CHECK(bounds.max().y() == Approx(42.5 + radius).margin(0.05));
  CHECK(bounds.max().z() == Approx(20 + 2 * radius).margin(0.05));
}

TEST_CASE("Buckling spring target: the graded spring's equilibrium under a uniform compression, as the solver finds it", "[examples][mechanics]") {
  // The committed target against an independent solve of what it claims to be: the graded spring
  // with every top node moved down by 15 %, simulated as `rodfab simulate` does. They must agree
  // within the solver's own error estimate, and the solve must show the published shape.
  const examples::SpringParameters p;
  mechanics::Design uniform(examples::bucklingSpring(p));
  uniform.mechanics = examples::bucklingSpringUniformCompression(p, 0.15);
  REQUIRE(uniform.mechanics.supports.size() == 2 * static_cast<std::size_t>(p.nodesAround));
  const mechanics::Simulation sim = mechanics::simulate(uniform, {}, {}, uniform.mechanics.loadSteps);
  REQUIRE(sim.solution.steps.back().loadFactor == 1.0);
  REQUIRE(sim.estimate.available);
  const double tolerance = sim.estimate.positionError;
  INFO("estimated position error " << tolerance << " mm (" << sim.estimate.relative << " of the largest displacement)");
  CHECK(sim.estimate.relative < 1e-4);

  const mechanics::Design committed = mechanics::readDesign(RODFAB_SOURCE_DIR "/examples/buckling-spring.json");
  REQUIRE(committed.mechanics.loadCases.size() == 1);
  const mechanics::LoadCase& c = committed.mechanics.loadCases[0];
  CHECK(c.supports.size() == static_cast<std::size_t>(p.nodesAround) + 4);  // trained at four top nodes
  std::map<std::string, const mechanics::TargetRod*> byName;
  for (const mechanics::TargetRod& t : c.target) byName[t.rod] = &t;
  REQUIRE(byName.size() == uniform.rods.size());
  double worst = 0, middle = 0, ends = 0;
  for (std::size_t r = 0; r < uniform.rods.size(); ++r) {
    const geometry::NurbsCurve& drawn = uniform.rods[r].centerline();
    REQUIRE(byName.count(uniform.rods[r].name()) == 1);
    const mechanics::TargetRod& t = *byName[uniform.rods[r].name()];
    REQUIRE(t.orientation.has_value());  // the solved frames, so the target curvature includes twist
    for (int k = 0; k <= 8; ++k) {
      const double f = k / 8.0;
      const double u = drawn.domainBegin() + f * (drawn.domainEnd() - drawn.domainBegin());
      const double v = t.centerline.domainBegin() + f * (t.centerline.domainEnd() - t.centerline.domainBegin());
      worst = std::max(worst, (t.centerline.point(v) - sim.problem->position(sim.solution.state, r, u)).norm());
    }
    // Every top node 15 % lower (the ring arcs' ends); the struts buckled out at mid-height.
    const Vec3 from = drawn.point(0.5 * (drawn.domainBegin() + drawn.domainEnd()));
    const Vec3 to = t.centerline.point(0.5 * (t.centerline.domainBegin() + t.centerline.domainEnd()));
    if (std::abs(drawn.point(drawn.domainBegin()).z() - p.height) < 1e-9) {
      CHECK(t.centerline.point(t.centerline.domainBegin()).z() == Approx(0.85 * p.height).margin(1e-6));
      CHECK(t.centerline.point(t.centerline.domainEnd()).z() == Approx(0.85 * p.height).margin(1e-6));
    }
    const double bulge = std::hypot(to.x(), to.y()) - std::hypot(from.x(), from.y());
    if (std::abs(from.z() - 0.5 * p.height) < 0.1 * p.height) middle = std::max(middle, bulge);
    else if (std::abs(from.z() - 0.5 * p.height) > 0.4 * p.height) ends = std::max(ends, std::abs(bulge));
  }
  INFO("largest distance from the solve " << worst << " mm; bulge at mid-height " << middle << " mm, near the ends " << ends << " mm");
  CHECK(worst <= tolerance);
  CHECK(middle > 0.25 * 0.15 * p.height);
  CHECK(middle > 4 * ends);
}

TEST_CASE("Arm cast target: unrolled onto the plane of the crown, every strip straight and as long", "[examples]") {
  const geometry::RodStructure cast = examples::armCast();
  const mechanics::LoadCase c = examples::armCastFlattened();
  REQUIRE(c.target.size() == cast.rods.size());
  double yMax = 0;
  for (const mechanics::TargetRod& t : c.target) {
    INFO(t.rod);
    CHECK(t.centerline.arcLength() == Approx(lengthOf(cast, t.rod)).epsilon(2e-3));
    const Vec3 a = t.centerline.point(0.0), b = t.centerline.point(1.0), m = t.centerline.point(0.5);
    CHECK((m - 0.5 * (a + b)).norm() < 1e-6);  // straight
    for (const Vec3& q : {a, m, b}) {
      CHECK(q.z() == Approx(30.0).margin(1e-9));
      yMax = std::max(yMax, std::abs(q.y()));
    }
  }
  CHECK(yMax == Approx(30.0 * std::numbers::pi / 2).margin(1e-9));
}

namespace {

// Where each rod's ends are, in node units of the lattice (the ends are nodes by construction).
std::map<std::tuple<long, long, long>, int> rodsPerNode(const geometry::RodStructure& s, const Vec3& origin, const Vec3& spacing) {
  std::map<std::tuple<long, long, long>, int> count;
  for (const geometry::Rod& r : s.rods) {
    const auto& c = r.centerline();
    for (const Vec3& end : {c.point(c.domainBegin()), c.point(c.domainEnd())}) {
      const Vec3 unit = ((end - origin).array() / spacing.array()).matrix();
      const Vec3 rounded = unit.array().round().matrix();
      REQUIRE((unit - rounded).norm() < 1e-9);
      ++count[{std::lround(rounded.x()), std::lround(rounded.y()), std::lround(rounded.z())}];
    }
  }
  return count;
}

}  // namespace

TEST_CASE("Benchmark lattices: 1,520 rods joined at 8 x 8 x 9 nodes, filling the envelope", "[examples][benchmark]") {
  const Vec3 envelope(84.6, 84.6, 90.0);
  for (const std::string name : {"lattice", "curved-lattice"}) {
    INFO(name);
    const geometry::RodStructure s = examples::benchmarkDesign(name);
    REQUIRE(s.rods.size() == 7 * 8 * 9 + 8 * 7 * 9 + 8 * 8 * 8);
    // The solid fills the envelope: [0, envelope] up to the bounds' sampling pad.
    const geometry::Box3 box = s.bounds();
    CHECK((box.min().array().abs() < 1e-3).all());
    CHECK(((box.max() - envelope).array().abs() < 1e-3).all());
    // The first rod runs along x from the first node; its end is the next node: that fixes the lattice's
    // origin and spacing, and every rod end must then be a node, 2 to 6 rods at each of the 576.
    const auto& first = s.rods.front().centerline();
    const Vec3 origin = first.point(first.domainBegin());
    const double sx = (first.point(first.domainEnd()) - origin).x();
    const Vec3 spacing = ((envelope - 2.0 * origin).array() / Eigen::Array3d(7, 7, 8)).matrix();
    REQUIRE(sx == Approx(spacing.x()));
    const auto nodes = rodsPerNode(s, origin, spacing);
    REQUIRE(nodes.size() == 8 * 8 * 9);
    int corners = 0, sixes = 0;
    for (const auto& [node, n] : nodes) {
      CHECK(n >= 3);
      CHECK(n <= 6);
      corners += n == 3;
      sixes += n == 6;
    }
    CHECK(corners == 8);
    CHECK(sixes == 6 * 6 * 7);
    CHECK(connectedComponents(s, 1e-6) == 1);
    for (const geometry::Rod& r : s.rods) {
      REQUIRE(r.section().shape == geometry::SectionShape::Circle);
      REQUIRE(r.section().width == 1.5);
      // Straight rods are as long as the spacing along their axis; curved ones longer (bowed by 0.15 of it).
      const double chord = (r.centerline().point(r.centerline().domainEnd()) - r.centerline().point(r.centerline().domainBegin())).norm();
      if (name == "lattice") REQUIRE(r.length() == Approx(chord));
      else REQUIRE(r.length() > 1.04 * chord);
    }
    // E from the 8 MPa floor at mid-height to ~120 MPa at the top and bottom.
    const geometry::DesignSummary summary = geometry::summarize(s);
    CHECK(summary.modulusMin == Approx(8.0).margin(0.5));
    CHECK(summary.modulusMax > 110.0);
    CHECK(summary.modulusMax <= 120.0);
  }
}

TEST_CASE("Benchmark designs are valid design files, remade exactly", "[examples][benchmark]") {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("rodfab-test-benchmark-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (const std::string& name : examples::benchmarkClasses()) {
    INFO(name);
    const geometry::RodStructure s = examples::benchmarkDesign(name);
    // Written and read back (the reader validates every rod): the same design, and the same again when remade.
    geometry::writeDesign(s, dir / (name + ".json"));
    const geometry::RodStructure read = geometry::readDesign(dir / (name + ".json"));
    CHECK(geometry::designToJson(read) == geometry::designToJson(s));
    CHECK(geometry::designToJson(examples::benchmarkDesign(name)) == geometry::designToJson(s));
  }
  std::filesystem::remove_all(dir);
  // The dense block: one rectangular rod filling 84.6 x 84.6 x 9 mm exactly.
  const geometry::RodStructure block = examples::benchmarkDesign("dense");
  REQUIRE(block.rods.size() == 1);
  CHECK((block.bounds().min().array().abs() < 1e-6).all());
  CHECK(((block.bounds().max() - Vec3(84.6, 84.6, 9.0)).array().abs() < 1e-6).all());
  CHECK(examples::benchmarkDesign("spring").rods.size() == 312);
  CHECK_THROWS_AS(examples::benchmarkDesign("sponge"), std::invalid_argument);
}
