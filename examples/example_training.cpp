// The bundled designs' training cases (mechanics blocks) and their target shapes.
#include "examples/example_designs.hpp"
#include "examples/example_curves.hpp"
#include "mechanics/mechanics.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace rodfab::examples {

using namespace detail;

namespace {

mechanics::RodEndRef placeAt(const Vec3& p, const std::string& path) {
  mechanics::RodEndRef ref;
  ref.point = p;
  ref.path = path;
  return ref;
}

mechanics::MechanicsSpec trainingSpec(int loadSteps) {
  mechanics::MechanicsSpec spec;
  spec.present = true;
  spec.loadSteps = loadSteps;
  return spec;
}

mechanics::Support support(const Vec3& p, std::size_t index, mechanics::SupportKind kind, const Vec3& displacement = Vec3::Zero()) {
  mechanics::Support s;
  s.at = placeAt(p, "mechanics.supports[" + std::to_string(index) + "].at");
  s.kind = kind;
  s.displacement = displacement;
  return s;
}

}  // namespace

mechanics::MechanicsSpec unfoldingBoxTraining(double force) {
  constexpr double kSide = 20.0, kPitch = kSide + 2.5;  // as in unfoldingBox()
  mechanics::MechanicsSpec spec = trainingSpec(20);
  const Vec3 base(kPitch, kPitch, 0);
  for (const Vec3& corner : {Vec3(0, 0, 0), Vec3(kSide, 0, 0), Vec3(kSide, kSide, 0), Vec3(0, kSide, 0)})
    spec.supports.push_back(support(base + corner, spec.supports.size(), mechanics::SupportKind::Clamped));
  // The middle of each outer square's outer edge.
  const Vec3 outerEdges[] = {Vec3(kPitch + 0.5 * kSide, 0, 0),                   // square 10
                             Vec3(0, kPitch + 0.5 * kSide, 0),                   // square 01
                             Vec3(2 * kPitch + kSide, kPitch + 0.5 * kSide, 0),  // square 21
                             Vec3(kPitch + 0.5 * kSide, 3 * kPitch + kSide, 0)};  // square 13 (the lid)
  for (const Vec3& middle : outerEdges) {
    mechanics::PointLoad load;
    load.at = placeAt(middle, "mechanics.loads[" + std::to_string(spec.loads.size()) + "].at");
    // Normal to the square (and so perpendicular to its outer edge), turning with it as it folds.
    load.force = force * Vec3(0, 0, 1);
    load.follower = true;
    spec.loads.push_back(load);
  }
  return spec;
}

namespace {

// The spring's bottom-ring nodes clamped and `pushed` equidistant top-ring nodes pinned and moved
// down by `compression` of its height.
mechanics::MechanicsSpec springCompressedAt(const SpringParameters& p, double compression, int pushed) {
  mechanics::MechanicsSpec spec = trainingSpec(20);
  const double dTheta = 2.0 * kPi / p.nodesAround;
  auto node = [&](int i, int level) {  // as nodeAngle in bucklingSpring()
    const double a = dTheta * (i + 0.5 * (level % 2));
    return Vec3(p.radius * std::cos(a), p.radius * std::sin(a), p.height * level / p.levels);
  };
  for (int i = 0; i < p.nodesAround; ++i)
    spec.supports.push_back(support(node(i, 0), spec.supports.size(), mechanics::SupportKind::Clamped));
  for (int k = 0; k < pushed; ++k)
    spec.supports.push_back(support(node(k * p.nodesAround / pushed, p.levels), spec.supports.size(), mechanics::SupportKind::Pinned,
                                    Vec3(0, 0, -compression * p.height)));
  return spec;
}

}  // namespace

mechanics::MechanicsSpec bucklingSpringTraining(const SpringParameters& p, double compression) {
  return springCompressedAt(p, compression, 4);
}

mechanics::MechanicsSpec bucklingSpringUniformCompression(const SpringParameters& p, double compression) {
  return springCompressedAt(p, compression, p.nodesAround);
}

mechanics::MechanicsSpec armCastTraining(double fraction) {
  constexpr double kRadius = 30.0, kLength = 70.0;  // as in armCast()
  mechanics::MechanicsSpec spec = trainingSpec(20);
  // Unrolled onto the plane z = R tangent to the crown, the rim at angle 0 lands at y = R pi / 2,
  // z = R, the one at pi at y = -R pi / 2.
  const geometry::RodStructure cast = armCast();
  std::vector<Vec3> rimEnds;
  for (const Rod& rod : cast.rods)
    for (const Vec3& p : {rod.centerline().points().front(), rod.centerline().points().back()})
      if (std::abs(p.z()) < 1e-9 && p.x() > -1e-9 && p.x() < kLength + 1e-9) rimEnds.push_back(p);
  std::sort(rimEnds.begin(), rimEnds.end(), [](const Vec3& a, const Vec3& b) {
    return std::make_tuple(a.y(), a.x()) < std::make_tuple(b.y(), b.x());
  });
  rimEnds.erase(std::unique(rimEnds.begin(), rimEnds.end(), [](const Vec3& a, const Vec3& b) { return (a - b).norm() < 1e-6; }),
                rimEnds.end());
  for (const Vec3& p : rimEnds) {
    const double side = p.y() > 0 ? 1.0 : -1.0;
    const Vec3 flat(p.x(), side * kRadius * kPi / 2, kRadius);
    // Held flat, as hands would: clamped and turned a quarter turn about the cast's axis (x), so the
    // strip's d1, the surface normal (+-y on the rims), becomes +z. Pinned rims keep their curl.
    mechanics::Support held = support(p, spec.supports.size(), mechanics::SupportKind::Clamped, fraction * (flat - p));
    held.rotation = Vec3(fraction * side * kPi / 2, 0, 0);
    spec.supports.push_back(held);
  }
  return spec;
}

// ---- Training targets ------------------------------------------------------------------------

namespace {

// The target of `rod` under the deformation `map` of space: its centerline through the mapped
// points at a quarter of its parameter apart (cubic, parameter kept), the frame seeded with the
// design's d1 at the start carried by the map's differential (a central difference).
mechanics::TargetRod mappedTarget(const Rod& rod, const std::function<Vec3(const Vec3&)>& map) {
  const NurbsCurve& c = rod.centerline();
  const double a = c.domainBegin(), b = c.domainEnd();
  mechanics::TargetRod t;
  t.rod = rod.name();
  t.centerline = cubicThrough([&](double s) { return map(c.point(a + s * (b - a))); });
  const Vec3 start = c.point(a), d1 = rod.frame().at(c, a).d1;
  constexpr double h = 1e-4;
  t.referenceNormal = ((map(start + h * d1) - map(start - h * d1)) / (2 * h)).normalized();
  return t;
}

mechanics::LoadCase trainingCase(std::string name, const mechanics::MechanicsSpec& training) {
  mechanics::LoadCase lc;
  lc.name = std::move(name);
  lc.supports = training.supports;
  lc.loads = training.loads;
  lc.distributedLoads = training.distributedLoads;
  lc.loadSteps = training.loadSteps;
  lc.path = "mechanics.load_cases[0]";
  return lc;
}

// One fold of the box net about the edge line through `edge` along `axis`: points beyond the gap
// (outwards `out`, in the plane) turn up by 90 degrees rigidly; points in the gap lie on a quarter
// circle of radius 2 gap / pi, so a hinge keeps its length. C1 across the gap's far side.
struct Fold {
  Vec3 edge, axis, out;
  double gap;
  Vec3 operator()(const Vec3& p) const {
    const Vec3 r = p - edge, up(0, 0, 1);
    const double along = r.dot(axis), d = r.dot(out), h = r.z(), radius = 2 * gap / kPi;
    if (d >= gap) return edge + along * axis + (radius - h) * out + (radius + d - gap) * up;
    const double phi = std::max(d, 0.0) / gap * 0.5 * kPi;
    return edge + along * axis + radius * (std::sin(phi) * out + (1 - std::cos(phi)) * up) +
           h * (-std::sin(phi) * out + std::cos(phi) * up);
  }
};

// The target rods in name order, the order a design file's "rods" object is read back in.
mechanics::LoadCase sortedByName(mechanics::LoadCase lc) {
  std::sort(lc.target.begin(), lc.target.end(), [](const mechanics::TargetRod& a, const mechanics::TargetRod& b) { return a.rod < b.rod; });
  return lc;
}

// The shape `design` takes under its mechanics block, simulated as `rodfab simulate` does with its
// defaults (degree 6, automatic spans, error estimate): every rod's solved centerline and frames.
// Throws std::runtime_error when the estimate is missing or above the default accuracy, so a
// target is never a poorly resolved solve.
std::vector<mechanics::TargetRod> simulatedShape(const mechanics::Design& design) {
  const mechanics::AccuracyOptions accuracy;
  const mechanics::Simulation sim = mechanics::simulate(design, {}, {}, design.mechanics.loadSteps, accuracy);
  if (!sim.estimate.available || sim.estimate.relative > accuracy.tolerance)
    throw std::runtime_error(design.source + ": the simulated target's error estimate is not below " +
                             std::to_string(accuracy.tolerance) + " (" + sim.estimate.note + ")");
  const mechanics::Design deformed = sim.problem->deformedStructure(sim.solution.state);
  std::vector<mechanics::TargetRod> target;
  for (const Rod& rod : deformed.rods) {
    mechanics::TargetRod t;
    t.rod = rod.name();
    t.centerline = rod.centerline();
    t.orientation = rod.orientation();
    target.push_back(std::move(t));
  }
  return target;
}

}  // namespace

mechanics::LoadCase unfoldingBoxFold(double force) {
  constexpr double kSide = 20.0, kGap = 2.5, kPitch = kSide + kGap;  // as in unfoldingBox()
  constexpr double lo = kPitch, hi = kPitch + kSide, eps = 1e-6;        // the middle square's sides
  const Fold front{Vec3(lo, lo, 0), Vec3(1, 0, 0), Vec3(0, -1, 0), kGap};  // square 10
  const Fold back{Vec3(lo, hi, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), kGap};    // square 12
  const Fold lid{Vec3(lo, hi + kPitch, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), kGap};  // square 13 on 12
  const Fold left{Vec3(lo, lo, 0), Vec3(0, 1, 0), Vec3(-1, 0, 0), kGap};   // square 01
  const Fold right{Vec3(hi, lo, 0), Vec3(0, 1, 0), Vec3(1, 0, 0), kGap};   // square 21
  mechanics::LoadCase lc = trainingCase("fold", unfoldingBoxTraining(force));
  for (const Rod& rod : unfoldingBox().rods) {
    // Each rod moves with the square (or gap) its middle lies in.
    const Vec3 m = rod.centerline().point(0.5 * (rod.centerline().domainBegin() + rod.centerline().domainEnd()));
    std::function<Vec3(const Vec3&)> map = [](const Vec3& p) { return p; };
    if (m.y() < lo - eps) map = front;
    else if (m.x() < lo - eps) map = left;
    else if (m.x() > hi + eps) map = right;
    else if (m.y() > hi + kPitch - eps) map = [&](const Vec3& p) { return back(lid(p)); };
    else if (m.y() > hi + eps) map = back;
    lc.target.push_back(mappedTarget(rod, map));
  }
  return sortedByName(std::move(lc));
}

mechanics::LoadCase bucklingSpringCompression(const SpringParameters& p, double compression) {
  mechanics::Design uniform(bucklingSpring(p));
  uniform.mechanics = bucklingSpringUniformCompression(p, compression);
  mechanics::LoadCase lc = trainingCase("compression", bucklingSpringTraining(p, compression));
  lc.target = simulatedShape(uniform);
  return sortedByName(std::move(lc));
}

mechanics::LoadCase armCastFlattened() {
  static constexpr double kRadius = 30.0;  // as in armCast()
  mechanics::LoadCase lc = trainingCase("flatten", armCastTraining());
  for (const Rod& rod : armCast().rods) {
    // The cylinder (x, R cos theta, R sin theta) unrolled: arc length R theta from the rim at theta = 0.
    mechanics::TargetRod t = mappedTarget(rod, [](const Vec3& q) {
      return Vec3(q.x(), kRadius * (0.5 * kPi - std::atan2(q.z(), q.y())), kRadius);
    });
    t.referenceNormal = Vec3(0, 0, 1);  // the strips' d1 (the surface normal) turned to the plane's
    lc.target.push_back(std::move(t));
  }
  return sortedByName(std::move(lc));
}

}  // namespace rodfab::examples
