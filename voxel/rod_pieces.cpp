#include "voxel/rod_pieces.hpp"

#include "voxel/rasterize.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <tuple>

namespace rodfab::voxel::detail {

using geometry::Vec3;

AffineInIndex affineInIndex(const PrinterGrid& grid, const Vec3& n, const Vec3& q) {
  const Vec3 origin(grid.origin.x(), grid.origin.y(), grid.origin.z());
  return {n.dot(origin - q), n.x() * grid.voxelSize.x(), n.y() * grid.voxelSize.y(), n.z() * grid.voxelSize.z()};
}

namespace {

// Everything the pieces need at one centerline parameter, from the exact geometry.
struct Node {
  double u;
  Vec3 r, t, d1, d2;
  double modulus;
  double curvature;  // 1/mm; 0 where the speed vanishes (the neighbouring nodes tell)
};

Node node(const geometry::Rod& rod, double u, bool fromBelow = false) {
  Vec3 d[3];
  if (fromBelow) rod.centerline().derivativesFromBelow(u, 2, d);
  else rod.centerline().derivatives(u, 2, d);
  const Vec3 t = fromBelow ? geometry::unitTangentFromBelow(d[1], d[2]) : geometry::unitTangent(d[1], d[2]);
  const geometry::Frame f = rod.frame().at(u, d[0], t);
  const double speed = d[1].norm();
  const double curvature = speed > 1e-14 ? d[1].cross(d[2]).norm() / (speed * speed * speed) : 0.0;
  return {u, d[0], t, f.d1, f.d2, rod.modulus().value(u), std::isfinite(curvature) ? curvature : 0.0};
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

// Fits the quadratic terms (coefficients of lambda (1 - lambda)) of `piece` and measures its error
// against points whose exact answer is known by construction: p = r(u) + x1 d1(u) + x2 d2(u) has
// closest point r(u) and frame coordinates (x1, x2) wherever the rod's radius is below its radius of
// curvature. Like the geometry's polyline deviation, the largest measured error is doubled (plus a
// floor) to bound the error between test points.
Measurement measure(const geometry::Rod& rod, const Node& a, const Node& b, RodPiece& piece) {
  Measurement m;
  const Node mid = node(rod, 0.5 * (a.u + b.u));
  const Node quarter[3] = {node(rod, a.u + 0.25 * (b.u - a.u)), mid, node(rod, a.u + 0.75 * (b.u - a.u))};
  double deviation = 0.0, curvature = std::max({a.curvature, b.curvature});
  for (const Node& n : quarter) {
    deviation = std::max(deviation, distanceToSegment(n.r, a.r, b.r));
    curvature = std::max(curvature, n.curvature);
  }
  m.chordDeviation = 2.0 * deviation + 1e-9;
  piece.x1Quadratic = piece.x2Quadratic = piece.modulusQuadratic = 0.0;
  piece.modulusBegin = a.modulus;
  piece.modulusEnd = b.modulus;
  std::tie(piece.modulusLow, piece.modulusHigh) = rod.modulus().valueBoundsOn(a.u, b.u);
  const double radius = rod.section().boundingRadius();
  // The slab of a piece holds the sections of its own centerline only while they do not reach the
  // centres of curvature, where the normal planes cross (curvature times radius below 1, with a 10 %
  // margin for the sampled curvature): past that the sections fold over and the piece goes exact.
  if (!(1.1 * curvature * radius < 1.0)) return m;
  const WorldEstimate centre = estimateAt(piece, a, b, mid.r);
  const double quadraticWeight = centre.estimate.lambda * (1.0 - centre.estimate.lambda);
  if (!centre.inSlab || !(quadraticWeight > 0.0)) return m;
  piece.x1Quadratic = -centre.estimate.x1 / quadraticWeight;
  piece.x2Quadratic = -centre.estimate.x2 / quadraticWeight;
  piece.modulusQuadratic = (mid.modulus - estimateModulus(piece, centre.estimate.lambda)) / quadraticWeight;

  constexpr int kDirections = 8;
  double coordinateError = 0.0, modulusError = 0.0;
  for (const Node& n : quarter) {
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
  return m;
}

openvdb::CoordBBox indexBox(const PrinterGrid& grid, const Vec3& lo, const Vec3& hi) {
  return grid.voxelsWithin({lo.x(), lo.y(), lo.z()}, {hi.x(), hi.y(), hi.z()});
}

}  // namespace

double minimumPieceLength(const PrinterGrid& grid) {
  return 0.25 * std::min({grid.voxelSize.x(), grid.voxelSize.y(), grid.voxelSize.z()});
}

std::size_t pieceBudget(const geometry::Rod& rod, const PrinterGrid& grid) {
  const double perLength = 4.0 * rod.length() / minimumPieceLength(grid);
  const double segments = double(rod.sampleParameters().size());
  return static_cast<std::size_t>(std::min(8.0 * segments + perLength, 1e15)) + 2 * rod.smoothPieces().size() + 64;
}

RodPieces buildRodPieces(const geometry::Rod& rod, const PrinterGrid& grid, const std::function<bool()>& interrupted) {
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
  const double minLength = minimumPieceLength(grid);
  const std::size_t budget = pieceBudget(rod, grid);
  // Pieces so far if no more splits came: the segments and the caps.
  std::size_t planned = rod.sampleParameters().size() - 1 + 2 * rod.smoothPieces().size(), steps = 0;

  std::vector<Node> nodes;  // one per plane
  auto finish = [&](const Node& a, const Node& b, double slack, RodPiece& piece) {
    piece.plane = static_cast<int>(nodes.size()) - 1;
    const Vec3 chord = b.r - a.r;
    piece.axisPoint = a.r;
    piece.axisDirection = chord.norm() > 0.0 ? Vec3(chord.normalized()) : a.t;
    piece.reach = boundingRadius + slack + 1e-7;
    piece.box = indexBox(grid, a.r.cwiseMin(b.r).array() - piece.reach, a.r.cwiseMax(b.r).array() + piece.reach);
    out.pieces.push_back(piece);
    nodes.push_back(b);
  };
  auto addSwept = [&](const Node& a, const Node& b, const Measurement& m, RodPiece piece) {
    piece.kind = RodPiece::Kind::Swept;
    piece.x1Begin = affineInIndex(grid, a.d1, a.r);
    piece.x2Begin = affineInIndex(grid, a.d2, a.r);
    piece.x1End = affineInIndex(grid, b.d1, b.r);
    piece.x2End = affineInIndex(grid, b.d2, b.r);
    piece.normalizedRadiusErrorBound = gaugeFactor * m.coordinateError * inverseMinHalf + 1e-12;
    // A voxel the piece owns is within the bounding radius of a centerline point of the piece, and
    // that point within the chord deviation of the chord; those decided exactly lie up to the
    // coordinate bound further out.
    finish(a, b, m.chordDeviation + m.coordinateError, piece);
  };
  auto addExact = [&](const Node& a, const Node& b, const Measurement& m) {
    RodPiece piece;
    piece.kind = RodPiece::Kind::Exact;
    piece.normalizedRadiusErrorBound = std::numeric_limits<double>::infinity();
    // Every point of the piece's centerline is within its deviation bound of the chord, or (where
    // the curve folds back) within half its polyline length of the chord's ends.
    finish(a, b, std::max(m.chordDeviation, 0.5 * ((b.r - a.r).norm() + 2.0 * m.chordDeviation)), piece);
  };
  auto refine = [&](auto&& self, const Node& a, const Node& b, int depth) -> void {
    if (interrupted && ++steps % 256 == 0 && interrupted()) throw Interrupted("rasterizer: interrupted while cutting rod '" + rod.name() + "' into pieces");
    RodPiece piece;
    const Measurement m = measure(rod, a, b, piece);
    const double modulusTolerance = 1e-6 * std::max({std::abs(a.modulus), std::abs(b.modulus), 1e-3});
    const bool modulusAccurate = m.modulusError <= modulusTolerance;
    const bool accurate = m.valid && m.coordinateError <= kCoordinateTolerance && modulusAccurate;
    // Splitting stops at the depth limit and when the rod's budget is spent, and for the geometry at
    // pieces shorter than the voxels can tell apart (where the sections fold over, or round-off far
    // from the origin dominates, it would not converge); E converges away from its rare jumps, which
    // the depth limit confines. What is left inaccurate keeps its measured bound or goes exact.
    const bool geometryAccurate = m.valid && m.coordinateError <= kCoordinateTolerance;
    const double length = (b.r - a.r).norm() + m.chordDeviation;
    if (!accurate && depth < kMaxRefinement && (geometryAccurate || length >= minLength) && planned < budget && b.u > a.u) {
      ++planned;
      const Node mid = node(rod, 0.5 * (a.u + b.u));
      self(self, a, mid, depth + 1);
      self(self, mid, b, depth + 1);
      return;
    }
    if (m.valid && modulusAccurate) addSwept(a, b, m, piece);
    else addExact(a, b, m);
  };

  const std::vector<double>& u = rod.sampleParameters();
  const geometry::BSplineField& modulus = rod.modulus();
  std::vector<RodPiece> caps;
  // The caps: the half-spaces beyond the end planes of every smooth piece. Flat caps own no voxels
  // beyond the plane, but voxel centres within round-off of it are handed to the exact test like any
  // other borderline case.
  const double capReach = std::max(boundingRadius, section.capRadius()) + 1e-7;
  auto addCap = [&](std::size_t plane, bool atEnd, float capModulus) {
    const Node& n = nodes[plane];
    RodPiece cap;
    cap.kind = atEnd ? RodPiece::Kind::EndCap : RodPiece::Kind::BeginCap;
    cap.plane = static_cast<int>(plane);
    for (int k = 0; k < 3; ++k) cap.capOffset[k] = affineInIndex(grid, Vec3::Unit(k), n.r);
    cap.capModulus = capModulus;
    cap.axisPoint = n.r;
    cap.axisDirection = n.t;
    cap.reach = capReach;
    cap.box = indexBox(grid, n.r.array() - capReach, n.r.array() + capReach);
    caps.push_back(cap);
  };
  const std::vector<geometry::SmoothPiece>& smooth = rod.smoothPieces();
  for (std::size_t k = 0; k < smooth.size(); ++k) {
    const geometry::SmoothPiece& sp = smooth[k];
    nodes.push_back(node(rod, u[sp.firstSample]));
    const std::size_t firstPlane = nodes.size() - 1;
    for (std::size_t s = sp.firstSample + 1; s <= sp.lastSample; ++s) {
      const Node a = nodes.back();
      refine(refine, a, node(rod, u[s], sp.endFromBelow && s == sp.lastSample), 0);
    }
    // E at the rod's ends as the field's own domain ends (it may differ from the centerline's by round-off).
    addCap(firstPlane, false, static_cast<float>(k == 0 ? modulus.value(modulus.domainBegin()) : modulus.value(sp.begin)));
    addCap(nodes.size() - 1, true,
           static_cast<float>(k + 1 == smooth.size() ? modulus.value(modulus.domainEnd()) : modulus.value(sp.end)));
  }
  for (const Node& n : nodes) out.planes.push_back(affineInIndex(grid, n.t, n.r));
  out.pieces.insert(out.pieces.end(), caps.begin(), caps.end());
  for (const RodPiece& p : out.pieces)
    if (!p.box.empty()) out.box.expand(p.box);
  return out;
}

}  // namespace rodfab::voxel::detail
