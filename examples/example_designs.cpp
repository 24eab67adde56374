#include "examples/example_designs.hpp"
#include "mechanics/mechanics.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <tuple>

namespace rodfab::examples {

using geometry::BSplineField;
using geometry::CapStyle;
using geometry::NurbsCurve;
using geometry::Rod;
using geometry::RodStructure;
using geometry::Section;
using geometry::Vec3;

namespace {

constexpr double kPi = std::numbers::pi;

NurbsCurve straight(const Vec3& a, const Vec3& b) { return NurbsCurve(1, {0, 0, 1, 1}, {a, b}); }

// Control points of the cubic Bezier that passes through s[0..3] at t = 0, 1/3, 2/3, 1.
template <class T>
std::vector<T> bezierThrough(const std::array<T, 4>& s) {
  return {s[0], T((-5.0 * s[0] + 18.0 * s[1] - 9.0 * s[2] + 2.0 * s[3]) / 6.0),
          T((2.0 * s[0] - 9.0 * s[1] + 18.0 * s[2] - 5.0 * s[3]) / 6.0), s[3]};
}

NurbsCurve cubicThrough(const std::function<Vec3(double)>& q) {
  return NurbsCurve(3, {0, 0, 0, 0, 1, 1, 1, 1}, bezierThrough<Vec3>({q(0.0), q(1.0 / 3.0), q(2.0 / 3.0), q(1.0)}));
}

// Cubic quaternion spline through four samples of a rotation path (kept in one hemisphere, since
// q and -q are the same rotation but would interpolate through zero).
geometry::QuaternionSpline quaternionsThrough(const std::function<Eigen::Vector4d(double)>& q) {
  std::array<Eigen::Vector4d, 4> s = {q(0.0), q(1.0 / 3.0), q(2.0 / 3.0), q(1.0)};
  for (int i = 1; i < 4; ++i)
    if (s[i].dot(s[i - 1]) < 0.0) s[i] = -s[i];
  return geometry::QuaternionSpline(3, {0, 0, 0, 0, 1, 1, 1, 1}, bezierThrough(s));
}

// Circular arc about the z axis at height z, from angle a0 to a1 (|a1 - a0| < pi): one rational
// quadratic span, exact.
NurbsCurve ringArc(double radius, double a0, double a1, double z) {
  const double half = 0.5 * (a1 - a0), mid = 0.5 * (a0 + a1);
  const double w = std::cos(half);
  const Vec3 p0(radius * std::cos(a0), radius * std::sin(a0), z);
  const Vec3 p1(radius / w * std::cos(mid), radius / w * std::sin(mid), z);
  const Vec3 p2(radius * std::cos(a1), radius * std::sin(a1), z);
  return NurbsCurve(2, {0, 0, 0, 1, 1, 1}, {p0, p1, p2}, {1, w, 1});
}

// Piecewise-linear E(s) through the start, middle and end values.
BSplineField threePointModulus(double start, double middle, double end) {
  return BSplineField(1, {0, 0, 0.5, 1, 1}, {start, middle, end});
}

std::string numbered(const std::string& prefix, std::size_t i) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%03zu", i);
  return prefix + buf;
}

Rod circleRod(std::string name, NurbsCurve curve, double diameter, BSplineField modulus) {
  return Rod(std::move(name), std::move(curve), Section::circle(diameter), std::nullopt, std::nullopt,
             CapStyle::Round, std::move(modulus));
}

}  // namespace

RodStructure unfoldingBox() {
  constexpr double kSide = 20.0, kGap = 2.5, kPitch = kSide + kGap;
  constexpr double kEdgeDiameter = 1.5;
  // The cross-shaped net of a cube: a column of four squares with one on each side of the second.
  const std::pair<int, int> cells[] = {{1, 0}, {1, 1}, {1, 2}, {1, 3}, {0, 1}, {2, 1}};
  RodStructure s;
  s.source = "unfolding-box";
  // Stiff in the middle of each edge, softer towards the corners so the frames stay square when folded.
  const BSplineField edgeModulus(1, {0, 0, 0.25, 0.75, 1, 1}, {40, 120, 120, 40});
  for (const auto& [cx, cy] : cells) {
    const Vec3 o(cx * kPitch, cy * kPitch, 0.0);
    const Vec3 c[4] = {o, o + Vec3(kSide, 0, 0), o + Vec3(kSide, kSide, 0), o + Vec3(0, kSide, 0)};
    for (int e = 0; e < 4; ++e)
      s.rods.push_back(circleRod("square" + std::to_string(cx) + std::to_string(cy) + "-edge" + std::to_string(e),
                                 straight(c[e], c[(e + 1) % 4]), kEdgeDiameter, edgeModulus));
  }
  // Hinges: two short soft rods across each gap between neighbouring squares, at a quarter and three
  // quarters of the shared side. Elliptic, thin out of the plane (d1 = the plane normal), at the floor.
  const std::tuple<std::pair<int, int>, std::pair<int, int>> neighbours[] = {
      {{1, 0}, {1, 1}}, {{1, 1}, {1, 2}}, {{1, 2}, {1, 3}}, {{0, 1}, {1, 1}}, {{1, 1}, {2, 1}}};
  int hinge = 0;
  for (const auto& [a, b] : neighbours) {
    const bool vertical = a.first == b.first;  // b above a: hinge runs along y across the gap
    for (double f : {0.25, 0.75}) {
      Vec3 from, to;
      if (vertical) {
        from = Vec3(a.first * kPitch + f * kSide, a.second * kPitch + kSide, 0);
        to = Vec3(b.first * kPitch + f * kSide, b.second * kPitch, 0);
      } else {
        from = Vec3(a.first * kPitch + kSide, a.second * kPitch + f * kSide, 0);
        to = Vec3(b.first * kPitch, b.second * kPitch + f * kSide, 0);
      }
      s.rods.emplace_back("hinge-" + std::to_string(hinge++), straight(from, to), Section::ellipse(0.9, 1.5),
                          Vec3(0, 0, 1), std::nullopt, CapStyle::Round, BSplineField::constant(8.0, 0, 1));
    }
  }
  return s;
}

RodStructure bucklingSpring(const SpringParameters& p) {
  RodStructure s;
  s.source = "buckling-spring";
  const double dTheta = 2.0 * kPi / p.nodesAround;
  auto modulusAt = [&](double z) {
    const double t = std::abs(z / p.height - 0.5) * 2.0;
    return p.modulusMiddle + (p.modulusEnds - p.modulusMiddle) * t * t;
  };
  auto nodeAngle = [&](int i, int level) { return dTheta * (i + 0.5 * (level % 2)); };
  std::size_t strut = 0;
  for (int level = 0; level < p.levels; ++level) {
    const double z0 = p.height * level / p.levels, z1 = p.height * (level + 1) / p.levels;
    for (int i = 0; i < p.nodesAround; ++i) {
      const double a0 = nodeAngle(i, level);
      for (double side : {-0.5, 0.5}) {
        const double a1 = a0 + side * dTheta;
        auto helix = [&](double t) {
          const double a = a0 + t * (a1 - a0);
          return Vec3(p.radius * std::cos(a), p.radius * std::sin(a), z0 + t * (z1 - z0));
        };
        s.rods.push_back(circleRod(numbered("strut-", strut++), cubicThrough(helix), p.rodDiameter,
                                   threePointModulus(modulusAt(z0), modulusAt(0.5 * (z0 + z1)), modulusAt(z1))));
      }
    }
  }
  std::size_t arc = 0;
  for (int level : {0, p.levels}) {
    const double z = p.height * level / p.levels;
    for (int i = 0; i < p.nodesAround; ++i)
      s.rods.push_back(circleRod(numbered("ring-", arc++),
                                 ringArc(p.radius, nodeAngle(i, level), nodeAngle(i + 1, level), z), p.rodDiameter,
                                 BSplineField::constant(modulusAt(z), 0, 1)));
  }
  return s;
}

RodStructure bucklingSpringScaledTo(const Vec3& envelope, double rodDiameter) {
  SpringParameters p;
  p.rodDiameter = rodDiameter;
  // The solid's size is scale * (centerline extent) + d per axis; measure the extent once at scale 1
  // (the struts bulge slightly past the nominal radius) and take the largest scale that fits.
  const Vec3 extent = bucklingSpring(p).bounds().sizes() - Vec3::Constant(rodDiameter);
  const double scale = ((envelope - Vec3::Constant(rodDiameter)).array() / extent.array()).minCoeff();
  p.radius *= scale;
  p.height *= scale;
  RodStructure s = bucklingSpring(p);
  s.source = "buckling-spring-scaled";
  return s;
}

namespace {

using Point2 = Eigen::Vector2d;
using PointKey = std::pair<long, long>;  // a point to 1 um
// Segments by their ends' keys, lower key first: a sorted map keeps the order deterministic and keeps
// a segment met twice once.
using SegmentMap = std::map<std::pair<PointKey, PointKey>, std::pair<Point2, Point2>>;

void addSegment(SegmentMap& segments, Point2 a, Point2 b) {
  auto key = [](const Point2& q) { return PointKey(std::lround(q.x() * 1000.0), std::lround(q.y() * 1000.0)); };
  PointKey ka = key(a), kb = key(b);
  if (ka == kb) return;
  if (kb < ka) std::swap(ka, kb), std::swap(a, b);
  segments.emplace(std::make_pair(ka, kb), std::make_pair(a, b));
}

// Liang-Barsky clipping of the segment ab to [0, width] x [0, height]; false when nothing is left.
bool clipToRectangle(const Point2& a, const Point2& b, double width, double height, Point2& ca, Point2& cb) {
  double t0 = 0.0, t1 = 1.0;
  const Point2 d = b - a;
  const double p[4] = {-d.x(), d.x(), -d.y(), d.y()};
  const double q[4] = {a.x(), width - a.x(), a.y(), height - a.y()};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0.0) {
      if (q[i] < 0.0) return false;
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0.0) t0 = std::max(t0, t); else t1 = std::min(t1, t);
  }
  if (t1 - t0 < 1e-9) return false;
  ca = a + t0 * d;
  cb = a + t1 * d;
  return true;
}

// The edges of pointy-top hexagons of edge `cell` clipped to [0, width] x [0, height], without
// slivers (a quarter of the edge or less) and without pieces along the border.
SegmentMap hexagonLattice(double width, double height, double cell) {
  SegmentMap edges;
  const double dx = std::sqrt(3.0) * cell, dy = 1.5 * cell;
  for (int row = -1; row * dy <= height + 2 * cell; ++row) {
    for (int col = -1; col * dx <= width + 2 * cell; ++col) {
      const Point2 centre(dx * (col + 0.5 * (row & 1)), dy * row);
      for (int k = 0; k < 6; ++k) {
        const double a0 = kPi / 6 + k * kPi / 3, a1 = a0 + kPi / 3;
        Point2 ca, cb;
        if (!clipToRectangle(centre + cell * Point2(std::cos(a0), std::sin(a0)), centre + cell * Point2(std::cos(a1), std::sin(a1)),
                             width, height, ca, cb))
          continue;
        // Drop slivers along the border: they duplicate the rim rods.
        const bool alongBorder = (std::abs(ca.x() - cb.x()) < 1e-9 && (std::abs(ca.x()) < 1e-9 || std::abs(ca.x() - width) < 1e-9)) ||
                                 (std::abs(ca.y() - cb.y()) < 1e-9 && (std::abs(ca.y()) < 1e-9 || std::abs(ca.y() - height) < 1e-9));
        if ((cb - ca).norm() > 0.25 * cell && !alongBorder) addSegment(edges, ca, cb);
      }
    }
  }
  return edges;
}

// The rim: the border of [0, width] x [0, height], split where edges end on it so joints are rod ends.
void addRim(SegmentMap& edges, double width, double height) {
  std::vector<Point2> border = {{0, 0}, {width, 0}, {width, height}, {0, height}};
  for (const auto& [k, e] : edges)
    for (const Point2& q : {e.first, e.second})
      if (q.x() < 1e-9 || q.x() > width - 1e-9 || q.y() < 1e-9 || q.y() > height - 1e-9) border.push_back(q);
  auto perimeter = [&](const Point2& q) {  // position along the border, counter-clockwise from (0, 0)
    if (q.y() < 1e-9) return q.x();
    if (q.x() > width - 1e-9) return width + q.y();
    if (q.y() > height - 1e-9) return 2 * width + height - q.x();
    return 2 * width + 2 * height - q.y();
  };
  std::sort(border.begin(), border.end(), [&](const Point2& a, const Point2& b) { return perimeter(a) < perimeter(b); });
  for (std::size_t i = 0; i < border.size(); ++i) addSegment(edges, border[i], border[(i + 1) % border.size()]);
}

}  // namespace

RodStructure armCast() {
  constexpr double kRadius = 30.0, kLength = 70.0, kCell = 7.25;  // mm; kCell = hexagon edge length
  const double arcLength = kPi * kRadius;
  using Point = Point2;  // unrolled cast: x = arc length around, y = axial
  SegmentMap edges = hexagonLattice(arcLength, kLength, kCell);
  addRim(edges, arcLength, kLength);

  auto onCylinder = [&](const Point& q) {
    const double theta = q.x() / kRadius;
    return Vec3(q.y(), kRadius * std::cos(theta), kRadius * std::sin(theta));
  };
  auto modulusAt = [&](double s) {
    // 0 on the crown, 1 on the rims. The crown at 39 MPa, the middle of the printable 8..190 MPa on
    // a log scale: with 8 or 12 MPa there (a rim-to-crown contrast of 15 or 10) the flattening with
    // clamped, turned rims meets a limit point at 75 or 80 % of the load (optimize/README.md).
    const double t = std::abs(s / arcLength - 0.5) * 2.0;
    return 39.0 + 81.0 * t * t;
  };
  RodStructure cast;
  cast.source = "arm-cast";
  std::size_t n = 0;
  for (const auto& [k, e] : edges) {
    const auto& [p0, p1] = e;
    auto path = [&](double t) { return onCylinder(p0 + t * (p1 - p0)); };
    // d1 = the surface normal: the strip is 1.0 mm thick through the cast and 2.0 mm wide across it.
    // A rotation-minimizing frame would drift off the normal along these helical paths, so the frame
    // is given as a quaternion spline, the way a rod solver writes it.
    auto frame = [&](double t) {
      const Point q = p0 + t * (p1 - p0);
      const double theta = q.x() / kRadius;
      const Vec3 normal(0, std::cos(theta), std::sin(theta));
      const Vec3 tangent = Vec3(p1.y() - p0.y(), -std::sin(theta) * (p1.x() - p0.x()), std::cos(theta) * (p1.x() - p0.x())).normalized();
      Eigen::Matrix3d r;
      r << normal, tangent.cross(normal), tangent;
      const Eigen::Quaterniond quat(r);
      return Eigen::Vector4d(quat.w(), quat.x(), quat.y(), quat.z());
    };
    cast.rods.emplace_back(numbered("strip-", n++), cubicThrough(path), Section::rectangle(1.0, 2.0), std::nullopt,
                           quaternionsThrough(frame), CapStyle::Round,
                           threePointModulus(modulusAt(p0.x()), modulusAt(0.5 * (p0.x() + p1.x())), modulusAt(p1.x())));
  }
  return cast;
}

// ---- Training cases ------------------------------------------------------------------------

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

}  // namespace rodfab::examples

// ---- Training targets ------------------------------------------------------------------------

namespace rodfab::examples {

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

// ---- Benchmark designs ----------------------------------------------------------------------

namespace rodfab::examples {

namespace {

// The lattice with node (i, j, k) at origin + spacing * (i, j, k) (componentwise): every centerline is
// the same affine image of the lattice in node units, so its extent scales per axis with `spacing`.
RodStructure cubicLattice(const LatticeParameters& p, const Vec3& origin, const Vec3& spacing, double envelopeHeight) {
  RodStructure s;
  s.source = p.bow > 0.0 ? "curved-lattice" : "lattice";
  auto place = [&](const Vec3& unit) { return Vec3(origin + spacing.cwiseProduct(unit)); };
  auto modulusAt = [&](double z) {
    const double t = std::abs(z / envelopeHeight - 0.5) * 2.0;
    return 8.0 + 112.0 * t * t;
  };
  const char* axisName[3] = {"x-", "y-", "z-"};
  for (int axis = 0; axis < 3; ++axis) {
    const Eigen::Vector3i step = Eigen::Vector3i::Unit(axis);
    const Vec3 side = Vec3::Unit((axis + 1) % 3);
    std::size_t n = 0;
    for (int k = 0; k + step.z() < p.nodes.z(); ++k)
      for (int j = 0; j + step.y() < p.nodes.y(); ++j)
        for (int i = 0; i + step.x() < p.nodes.x(); ++i) {
          const Vec3 a(i, j, k), b = a + step.cast<double>();
          const double sign = (i + j + k) % 2 == 0 ? 1.0 : -1.0;
          const auto path = [&](double t) { return place(a + t * (b - a) + sign * p.bow * std::sin(kPi * t) * side); };
          NurbsCurve curve = p.bow > 0.0 ? cubicThrough(path) : straight(place(a), place(b));
          const BSplineField modulus = threePointModulus(modulusAt(path(0.0).z()), modulusAt(path(0.5).z()), modulusAt(path(1.0).z()));
          s.rods.push_back(circleRod(numbered(axisName[axis], n++), std::move(curve), p.rodDiameter, modulus));
        }
  }
  return s;
}

}  // namespace

RodStructure cubicLatticeScaledTo(const Vec3& envelope, const LatticeParameters& p) {
  if ((p.nodes.array() < 2).any() || !(p.rodDiameter > 0.0) || !(p.bow >= 0.0) || !((envelope.array() > p.rodDiameter).all()))
    throw std::invalid_argument("cubic lattice: need at least 2 nodes per axis, a positive diameter below the envelope, bow >= 0");
  // The solid reaches one radius beyond its centerlines on every side (caps, and the sections where a
  // bow peaks). Measure the centerlines' extent once in node units (a trial spacing), then solve for
  // the spacing and origin that put the solid at [0, envelope].
  const Vec3 trial = (envelope.array() / (p.nodes.cast<double>().array() - 1.0)).matrix();
  const geometry::Box3 b = cubicLattice(p, Vec3::Zero(), trial, envelope.z()).bounds();
  const double r = 0.5 * p.rodDiameter;
  const Vec3 unitMin = ((b.min().array() + r) / trial.array()).matrix();
  const Vec3 unitExtent = ((b.sizes().array() - p.rodDiameter) / trial.array()).matrix();
  const Vec3 spacing = ((envelope.array() - p.rodDiameter) / unitExtent.array()).matrix();
  return cubicLattice(p, (r - spacing.array() * unitMin.array()).matrix(), spacing, envelope.z());
}

RodStructure denseBlock(const Vec3& size) {
  RodStructure s;
  s.source = "dense-block";
  const NurbsCurve axis = straight(Vec3(0, 0.5 * size.y(), 0.5 * size.z()), Vec3(size.x(), 0.5 * size.y(), 0.5 * size.z()));
  s.rods.emplace_back("block", axis, Section::rectangle(size.y(), size.z()), Vec3(0, 1, 0), std::nullopt, CapStyle::Flat,
                      BSplineField(1, {0, 0, 1, 1}, {8.0, 190.0}));
  return s;
}

std::vector<std::string> benchmarkClasses() { return {"spring", "lattice", "curved-lattice", "dense"}; }

RodStructure benchmarkDesign(const std::string& name) {
  const Vec3 envelope(84.6, 84.6, 90.0);  // 2000 x 1000 x 3000 Connex3 voxels
  if (name == "spring") return bucklingSpringScaledTo(envelope);
  if (name == "lattice") return cubicLatticeScaledTo(envelope);
  if (name == "curved-lattice") {
    LatticeParameters p;
    p.bow = 0.15;
    return cubicLatticeScaledTo(envelope, p);
  }
  if (name == "dense") return denseBlock();
  throw std::invalid_argument("unknown benchmark design '" + name + "' (expected spring, lattice, curved-lattice or dense)");
}

}  // namespace rodfab::examples
