#include "voxel/rod_pieces.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace rodfab::voxel::detail {

using geometry::Vec3;

IndexForm indexForm(const PrinterGrid& grid, const Vec3& n, const Vec3& q) {
  const Vec3 origin(grid.origin.x(), grid.origin.y(), grid.origin.z());
  return {n.dot(origin - q), n.x() * grid.voxelSize.x(), n.y() * grid.voxelSize.y(), n.z() * grid.voxelSize.z()};
}

namespace {

// Everything the pieces need at one centerline parameter, from the exact geometry.
struct Node {
  double u;
  Vec3 r, t, d1, d2;
  double modulus;
};

Node node(const geometry::Rod& rod, double u) {
  Vec3 d[3];
  rod.centerline().derivatives(u, 2, d);
  const Vec3 t = geometry::unitTangent(d[1], d[2]);
  const geometry::Frame f = rod.frame().at(u, d[0], t);
  return {u, d[0], t, f.d1, f.d2, rod.modulus().value(u)};
}

double distanceToSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + s * ab - p).norm();
}

// The swept approximation evaluated at a world point (the rasterizer evaluates the same expressions
// through IndexForms; the two differ by round-off only).
struct WorldEstimate {
  bool inSlab;
  SweptEstimate estimate;
};
WorldEstimate estimateAt(const RodPiece& piece, const Node& a, const Node& b, const Vec3& p) {
  const Vec3 wa = p - a.r, wb = p - b.r;
  const double pa = a.t.dot(wa), pb = b.t.dot(wb);
  if (!(pa >= 0.0 && pb < 0.0)) return {false, {}};
  return {true, estimateSwept(piece, pa, pb, a.d1.dot(wa), a.d2.dot(wa), b.d1.dot(wb), b.d2.dot(wb))};
}

struct Measurement {
  bool valid = false;         // every test point fell between the piece's planes
  double coordinateError = 0; // bound on |x_estimated - x_exact| (mm)
  double modulusError = 0;    // bound on |E_estimated - E_exact| (MPa)
  double chordDeviation = 0;  // bound on the distance from the centerline to the chord (mm)
};

// Fits the bow terms of `piece` and measures its error against points whose exact answer is known
// by construction: p = r(u) + x1 d1(u) + x2 d2(u) has closest point r(u) and frame coordinates (x1, x2)
// wherever the rod's radius is below its radius of curvature. Like the geometry's polyline deviation,
// the largest measured error is doubled (plus a floor) to bound the error between test points.
Measurement measure(const geometry::Rod& rod, const Node& a, const Node& b, RodPiece& piece) {
  Measurement m;
  const Node mid = node(rod, 0.5 * (a.u + b.u));
  piece.x1Bow = piece.x2Bow = piece.modulusBow = 0.0;
  piece.modulusBegin = a.modulus;
  piece.modulusEnd = b.modulus;
  const WorldEstimate centre = estimateAt(piece, a, b, mid.r);
  const double bow = centre.estimate.lambda * (1.0 - centre.estimate.lambda);
  if (!centre.inSlab || !(bow > 0.0)) return m;
  piece.x1Bow = -centre.estimate.x1 / bow;
  piece.x2Bow = -centre.estimate.x2 / bow;
  piece.modulusBow = (mid.modulus - estimateModulus(piece, centre.estimate.lambda)) / bow;

  const double radius = rod.section().boundingRadius();
  constexpr int kDirections = 8;
  double coordinateError = 0.0, modulusError = 0.0, deviation = 0.0;
  for (const double f : {0.25, 0.5, 0.75}) {
    const Node n = f == 0.5 ? mid : node(rod, a.u + f * (b.u - a.u));
    deviation = std::max(deviation, distanceToSegment(n.r, a.r, b.r));
    for (const double rho : {0.0, 0.5 * radius, radius}) {
      for (int k = 0; k < (rho == 0.0 ? 1 : kDirections); ++k) {
        const double phi = 2.0 * std::numbers::pi * k / kDirections;
        const double x1 = rho * std::cos(phi), x2 = rho * std::sin(phi);
        const WorldEstimate e = estimateAt(piece, a, b, n.r + x1 * n.d1 + x2 * n.d2);
        if (!e.inSlab) return m;
        coordinateError = std::max({coordinateError, std::abs(e.estimate.x1 - x1), std::abs(e.estimate.x2 - x2)});
        modulusError = std::max(modulusError, std::abs(estimateModulus(piece, e.estimate.lambda) - n.modulus));
      }
    }
  }
  m.valid = true;
  m.coordinateError = 2.0 * coordinateError + 1e-9;
  m.modulusError = 2.0 * modulusError + 1e-9 * std::abs(mid.modulus);
  m.chordDeviation = 2.0 * deviation + 1e-9;
  return m;
}

openvdb::CoordBBox indexBox(const PrinterGrid& grid, const Vec3& lo, const Vec3& hi) {
  return grid.voxelsWithin({lo.x(), lo.y(), lo.z()}, {hi.x(), hi.y(), hi.z()});
}

}  // namespace

RodPieces buildRodPieces(const geometry::Rod& rod, const PrinterGrid& grid) {
  RodPieces out;
  const geometry::Section& section = rod.section();
  out.inverseHalfWidth = 2.0 / section.width;
  out.inverseHalfHeight = 2.0 / section.height;
  out.inverseCapRadius = 1.0 / section.capRadius();
  const double boundingRadius = section.boundingRadius();
  const double inverseMinHalf = std::max(out.inverseHalfWidth, out.inverseHalfHeight);
  // |d normalizedRadius| <= |(dx1, dx2)| / min half-dimension for ellipses; the rectangle's max-norm gauge
  // changes by at most max(|dx1|, |dx2|) / min half-dimension.
  const double gaugeFactor = section.shape == geometry::SectionShape::Rectangle ? 1.0 : std::numbers::sqrt2;
  constexpr int kMaxRefinement = 24;

  std::vector<Node> nodes;  // one per plane
  auto addSwept = [&](const Node& a, const Node& b, const Measurement& m, RodPiece piece) {
    piece.kind = RodPiece::Kind::Swept;
    piece.plane = static_cast<int>(nodes.size()) - 1;
    piece.x1Begin = indexForm(grid, a.d1, a.r);
    piece.x2Begin = indexForm(grid, a.d2, a.r);
    piece.x1End = indexForm(grid, b.d1, b.r);
    piece.x2End = indexForm(grid, b.d2, b.r);
    piece.normalizedRadiusBand = m.valid ? gaugeFactor * m.coordinateError * inverseMinHalf + 1e-12
                                         : std::numeric_limits<double>::infinity();
    const Vec3 chord = b.r - a.r;
    piece.axisPoint = a.r;
    piece.axisDirection = chord.norm() > 0.0 ? Vec3(chord.normalized()) : a.t;
    // A voxel the piece owns is within the bounding radius of a centerline point of the piece, and
    // that point within the chord deviation of the chord; those decided exactly lie up to the
    // coordinate bound further out.
    const double slack = m.valid ? m.chordDeviation + m.coordinateError : 0.5 * (b.r - a.r).norm() + boundingRadius;
    piece.reach = boundingRadius + slack + 1e-7;
    piece.box = indexBox(grid, a.r.cwiseMin(b.r).array() - piece.reach, a.r.cwiseMax(b.r).array() + piece.reach);
    out.pieces.push_back(piece);
    nodes.push_back(b);
  };
  auto refine = [&](auto&& self, const Node& a, const Node& b, int depth) -> void {
    RodPiece piece;
    const Measurement m = measure(rod, a, b, piece);
    const double modulusTolerance = 1e-6 * std::max({std::abs(a.modulus), std::abs(b.modulus), 1e-3});
    const bool accurate = m.valid && m.coordinateError <= kCoordinateTolerance && m.modulusError <= modulusTolerance;
    if (!accurate && depth < kMaxRefinement) {
      const Node mid = node(rod, 0.5 * (a.u + b.u));
      self(self, a, mid, depth + 1);
      self(self, mid, b, depth + 1);
      return;
    }
    addSwept(a, b, m, piece);
  };

  const std::vector<double>& u = rod.sampleParameters();
  nodes.push_back(node(rod, u.front()));
  for (std::size_t s = 1; s < u.size(); ++s) {
    const Node a = nodes.back();
    refine(refine, a, node(rod, u[s]), 0);
  }
  for (const Node& n : nodes) out.planes.push_back(indexForm(grid, n.t, n.r));

  // The caps: the half-spaces beyond the end planes. Flat caps own no voxels beyond the plane, but
  // voxel centres within round-off of it are handed to the exact test like any other borderline case.
  const double capReach = std::max(boundingRadius, section.capRadius()) + 1e-7;
  for (const bool atEnd : {false, true}) {
    const Node& n = atEnd ? nodes.back() : nodes.front();
    RodPiece cap;
    cap.kind = atEnd ? RodPiece::Kind::EndCap : RodPiece::Kind::BeginCap;
    cap.plane = atEnd ? static_cast<int>(nodes.size()) - 1 : 0;
    for (int k = 0; k < 3; ++k) cap.capOffset[k] = indexForm(grid, Vec3::Unit(k), n.r);
    cap.axisPoint = n.r;
    cap.axisDirection = n.t;
    cap.reach = capReach;
    cap.box = indexBox(grid, n.r.array() - capReach, n.r.array() + capReach);
    out.pieces.push_back(cap);
  }
  for (const RodPiece& p : out.pieces)
    if (!p.box.empty()) out.box.expand(p.box);
  return out;
}

}  // namespace rodfab::voxel::detail
