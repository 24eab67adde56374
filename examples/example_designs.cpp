// The bundled example designs (examples/*.json): the unfolding box, the buckling spring, the arm cast.
#include "examples/example_designs.hpp"
#include "examples/example_curves.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace rodfab::examples {

using namespace detail;

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

}  // namespace rodfab::examples
