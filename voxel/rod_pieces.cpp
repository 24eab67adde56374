#include "voxel/rod_pieces.hpp"

#include "geometry/segment.hpp"
#include "voxel/rasterize.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <tuple>

namespace rodfab::voxel::detail {

using geometry::distanceToSegment;
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

// Fits the terms of E in x1 and x2 (RodPiece::modulusAcross1, 2) to E across the middle section: what
// E leaves beyond the blend with q, divided by lambda (1 - lambda), between points a `radius` either
// side along d1 and along d2, over their difference in x1 and x2. E is the same across the section;
// lambda is not, where the curvature changes along the piece, and with q alone that drift set most of
// the curved rods' pieces. Leaves a term 0 where a point it needs is not between the planes.
void fitModulusAcross(RodPiece& piece, const Node& a, const Node& b, const Node& mid, double radius) {
  const auto residual = [&](const Vec3& p, SweptEstimate& at) {
    const WorldEstimate e = estimateAt(piece, a, b, p);
    at = e.estimate;
    const double weight = at.lambda * (1.0 - at.lambda);
    if (!e.inSlab || !(weight > 0.0)) return std::numeric_limits<double>::quiet_NaN();
    return (mid.modulus - modulusBlend(piece, at)) / weight;
  };
  for (const bool second : {false, true}) {
    const Vec3 side = radius * (second ? mid.d2 : mid.d1);
    SweptEstimate plus, minus;
    const double rise = residual(mid.r + side, plus) - residual(mid.r - side, minus);
    const double run = second ? plus.x2 - minus.x2 : plus.x1 - minus.x1;
    if (std::isfinite(rise) && run > 0.0) (second ? piece.modulusAcross2 : piece.modulusAcross1) = rise / run;
  }
}

// Fits the coordinates' terms across the section (RodPiece::x1Across1 ... x2Across2) to points `radius`
// either side of the middle section's centre along d1 and along d2: what the blend and its quadratic
// term miss there, divided by lambda (1 - lambda), over the difference of the blended coordinate. Off
// the axis the sections turn with the frame: on an arc turning by theta the blend misses x1 by about
// x1 theta^2 lambda (1 - lambda) / 2, a term in x1 that the quadratic term, fitted on the axis, cannot
// hold, and which set the curved rods' pieces (the error fell only as the square of their length).
// Leaves a term 0 where a point it needs is not between the planes.
// Both directions are fitted to the piece as it is without the terms (`base`); a term that comes out
// non-finite stays 0.
void fitCoordinatesAcross(RodPiece& piece, const Node& a, const Node& b, const Node& mid, double radius) {
  const RodPiece base = piece;
  for (const bool second : {false, true}) {
    double residual1[2], residual2[2], blend[2];
    bool between = true;
    for (const int s : {0, 1}) {
      const double offset = s == 0 ? radius : -radius;
      const WorldEstimate e = estimateAt(base, a, b, mid.r + offset * (second ? mid.d2 : mid.d1));
      const double weight = e.estimate.lambda * (1.0 - e.estimate.lambda);
      between = between && e.inSlab && weight > 0.0;
      if (!between) break;
      residual1[s] = ((second ? 0.0 : offset) - e.estimate.x1) / weight;
      residual2[s] = ((second ? offset : 0.0) - e.estimate.x2) / weight;
      blend[s] = second ? e.estimate.x2 - weight * base.x2Quadratic : e.estimate.x1 - weight * base.x1Quadratic;
    }
    const double run = between ? blend[0] - blend[1] : 0.0;
    if (!(run > 0.0)) continue;
    const double term1 = (residual1[0] - residual1[1]) / run, term2 = (residual2[0] - residual2[1]) / run;
    if (!std::isfinite(term1) || !std::isfinite(term2)) continue;
    (second ? piece.x1Across2 : piece.x1Across1) = term1;
    (second ? piece.x2Across2 : piece.x2Across1) = term2;
  }
}

// E's tolerance on a piece: 1e-6 relative (the fraction map's interpolation bound, materials/README.md).
double modulusTolerance(const Node& a, const Node& b) {
  return 1e-6 * std::max({std::abs(a.modulus), std::abs(b.modulus), 1e-3});
}

// A test point of `measure`: the estimate there and the exact E.
struct ModulusSample {
  SweptEstimate at;
  double exact;
};
// The larger of `largest` and `error`, NaN if either is: a term that came out non-finite must not read
// as no error (std::max drops a NaN second argument).
double largerError(double largest, double error) { return error <= largest ? largest : error; }

double largestModulusError(const RodPiece& piece, const ModulusSample* begin, const ModulusSample* end) {
  double error = 0.0;
  for (const ModulusSample* s = begin; s != end; ++s) error = largerError(error, std::abs(estimateModulus(piece, s->at) - s->exact));
  return error;
}

// The directions `measure` tests in each section: cos and sin of 2 pi k / 8, computed once (they were
// some 25 % of the pieces' construction on the curved lattice).
const std::array<std::array<double, 2>, 8>& testDirections() {
  static const std::array<std::array<double, 2>, 8> directions = [] {
    std::array<std::array<double, 2>, 8> d;
    for (std::size_t k = 0; k < d.size(); ++k) {
      const double phi = 2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(d.size());
      d[k] = {std::cos(phi), std::sin(phi)};
    }
    return d;
  }();
  return directions;
}

// The test points of `measure`: each of three sections (quarter, middle, three quarters along u) at its
// centre (the first of its points) and at 8 directions at half and at the whole bounding radius.
constexpr std::size_t kTestPoints = 3 * (1 + 2 * 8);

// Fits E's cubic term (RodPiece::modulusCubic) to the centerline at the quarter sections (their test
// points on the axis): what the blend and its quadratic term leave there, by least squares on the
// shape lambda (1 - lambda) (lambda - 1/2), which is about 0 in the middle, where the quadratic term
// was fitted. Along a curved rod lambda strays from the parameter u by a cubic part as well; with E
// linear in u, the error that part left fell as the cube of the piece's length and set most of the
// pieces of the curved lattice's rods along whose length E changes. The two points it is fitted to no
// longer test the axis: `measure` tests it at four more (modulusErrorBetween).
void fitModulusCubic(RodPiece& piece, const ModulusSample& quarter, const ModulusSample& threeQuarters) {
  double along = 0.0, norm = 0.0;
  for (const ModulusSample* s : {&quarter, &threeQuarters}) {
    const double lambda = s->at.lambda, shape = lambda * (1.0 - lambda) * (lambda - 0.5);
    along += (s->exact - modulusBlend(piece, s->at)) * shape;
    norm += shape * shape;
  }
  if (norm > 0.0 && std::isfinite(along / norm)) piece.modulusCubic = along / norm;
}

// E's largest error on the centerline at u an eighth, three, five and seven eighths along the piece,
// between the test sections: where E's refined terms were not fitted. A knot of E's field inside the
// piece (E only C2 there) puts its error's peak between the sections the terms were fitted to; tested
// at those alone, a piece kept its cubic term while E missed its tolerance by 37 % in between (a
// rectangle along an arc, E swinging between its bounds: tests/test_voxel.cpp). NaN where a point is
// not between the planes.
double modulusErrorBetween(const geometry::Rod& rod, const RodPiece& piece, const Node& a, const Node& b) {
  double error = 0.0;
  for (const double f : {0.125, 0.375, 0.625, 0.875}) {
    const double u = a.u + f * (b.u - a.u);
    const WorldEstimate e = estimateAt(piece, a, b, rod.centerline().point(u));
    error = largerError(error, e.inSlab ? std::abs(estimateModulus(piece, e.estimate) - rod.modulus().value(u))
                                        : std::numeric_limits<double>::quiet_NaN());
  }
  return error;
}

// The piece's largest coordinate error over the test points (nullopt when one of them is not between its
// planes), with the estimates and the exact E there in `samples`.
std::optional<double> testCoordinates(const RodPiece& piece, const Node& a, const Node& b, const Node (&sections)[3], double radius,
                                      std::array<ModulusSample, kTestPoints>& samples) {
  const auto& directions = testDirections();
  std::size_t count = 0;
  double coordinateError = 0.0;
  for (const Node& n : sections) {
    for (const double rho : {0.0, 0.5 * radius, radius}) {
      for (std::size_t k = 0; k < (rho == 0.0 ? 1 : directions.size()); ++k) {
        const double x1 = rho * directions[k][0], x2 = rho * directions[k][1];
        const WorldEstimate e = estimateAt(piece, a, b, n.r + x1 * n.d1 + x2 * n.d2);
        if (!e.inSlab) return std::nullopt;
        coordinateError = largerError(largerError(coordinateError, std::abs(e.estimate.x1 - x1)), std::abs(e.estimate.x2 - x2));
        samples[count++] = {e.estimate, n.modulus};
      }
    }
  }
  return coordinateError;
}

struct Measurement {
  bool valid = false;         // every test point fell between the piece's planes
  double coordinateError = 0; // bound on |x_estimated - x_exact| (mm)
  double modulusError = 0;    // bound on |E_estimated - E_exact| (MPa)
  double chordDeviation = 0;  // bound on the distance from the centerline to the chord (mm)
  Node mid;                   // the node halfway along u, where `refine` splits the piece
};

// Fits the quadratic terms (coefficients of lambda (1 - lambda)) of `piece` and measures its error
// against points whose exact answer is known by construction: p = r(u) + x1 d1(u) + x2 d2(u) has
// closest point r(u) and frame coordinates (x1, x2) wherever the rod's radius is below its radius of
// curvature. Like the geometry's polyline deviation, the largest measured error is doubled (plus a
// floor) to bound the error between test points. Where the coordinates or E miss their tolerance, the
// terms across (and E's cubic term) are fitted and kept if they lower the measured error; E's refined
// terms are tested on the axis between the sections too (modulusErrorBetween).
Measurement measure(const geometry::Rod& rod, const Node& a, const Node& b, RodPiece& piece) {
  Measurement m;
  m.mid = node(rod, 0.5 * (a.u + b.u));
  const Node& mid = m.mid;
  const Node quarter[3] = {node(rod, a.u + 0.25 * (b.u - a.u)), mid, node(rod, a.u + 0.75 * (b.u - a.u))};
  double deviation = 0.0, curvature = std::max({a.curvature, b.curvature});
  for (const Node& n : quarter) {
    deviation = std::max(deviation, distanceToSegment(n.r, a.r, b.r));
    curvature = std::max(curvature, n.curvature);
  }
  m.chordDeviation = 2.0 * deviation + 1e-9;
  piece.x1Quadratic = piece.x2Quadratic = piece.modulusQuadratic = 0.0;
  piece.x1Across1 = piece.x1Across2 = piece.x2Across1 = piece.x2Across2 = 0.0;
  piece.modulusCubic = piece.modulusAcross1 = piece.modulusAcross2 = 0.0;
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
  piece.modulusQuadratic = (mid.modulus - estimateModulus(piece, centre.estimate)) / quadraticWeight;

  std::array<ModulusSample, kTestPoints> samples;
  std::optional<double> coordinateError = testCoordinates(piece, a, b, quarter, radius, samples);
  if (!coordinateError) return m;
  if (2.0 * *coordinateError + 1e-9 > kCoordinateTolerance) {
    // The terms across only where the coordinates miss their tolerance without them, as E's below.
    const RodPiece without = piece;
    fitCoordinatesAcross(piece, a, b, mid, radius);
    std::array<ModulusSample, kTestPoints> across;
    const std::optional<double> acrossError = testCoordinates(piece, a, b, quarter, radius, across);
    if (acrossError && *acrossError < *coordinateError) {
      coordinateError = acrossError;
      samples = across;
    } else {
      piece = without;
    }
  }
  m.valid = true;
  m.coordinateError = 2.0 * *coordinateError + 1e-9;
  const auto bound = [&](double largest) { return 2.0 * largest + 1e-9 * std::abs(mid.modulus); };
  m.modulusError = bound(largestModulusError(piece, samples.data(), samples.data() + samples.size()));
  // E's cubic term and terms across the section only where E misses its tolerance without them:
  // elsewhere the voxel loop may keep the shorter expression (LeafBuilder::sweep).
  if (m.modulusError > modulusTolerance(a, b)) {
    const RodPiece without = piece;
    fitModulusCubic(piece, samples[0], samples[kTestPoints - kTestPoints / 3]);
    fitModulusAcross(piece, a, b, mid, radius);
    const double refined = bound(largerError(largestModulusError(piece, samples.data(), samples.data() + samples.size()),
                                             modulusErrorBetween(rod, piece, a, b)));
    if (refined < m.modulusError) m.modulusError = refined;
    else piece = without;
  }
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

namespace {

// Cuts one rod into pieces: the refinement of every polyline segment (refine), the pieces it emits
// (addSwept, addExact) and the caps at the ends of every smooth piece (addCap). Pieces are appended in
// the order the planes are made, so a rod always gets the same pieces.
class PieceBuilder {
 public:
  PieceBuilder(const geometry::Rod& rod, const PrinterGrid& grid, const std::function<bool()>& interrupted)
      : rod_(rod), grid_(grid), interrupted_(interrupted), minLength_(minimumPieceLength(grid)),
        budget_(pieceBudget(rod, grid)),
        planned_(rod.sampleParameters().size() - 1 + 2 * rod.smoothPieces().size()) {
    const geometry::Section& section = rod.section();
    out_.inverseHalfWidth = 2.0 / section.width;
    out_.inverseHalfHeight = 2.0 / section.height;
    out_.inverseCapRadius = 1.0 / section.capRadius();
    boundingRadius_ = section.boundingRadius();
    inverseMinHalf_ = std::max(out_.inverseHalfWidth, out_.inverseHalfHeight);
    // |d normalizedRadius| <= |(dx1, dx2)| / min half-dimension for ellipses; the rectangle's max-norm
    // gauge changes by at most max(|dx1|, |dx2|) / min half-dimension.
    gaugeFactor_ = section.shape == geometry::SectionShape::Rectangle ? 1.0 : std::numbers::sqrt2;
    // Flat caps own no voxels beyond the plane, but voxel centres within round-off of it are handed to
    // the exact test like any other borderline case.
    capReach_ = std::max(boundingRadius_, section.capRadius()) + 1e-7;
  }

  RodPieces build() {
    const std::vector<geometry::SmoothPiece>& smooth = rod_.smoothPieces();
    for (std::size_t k = 0; k < smooth.size(); ++k) cutSmoothPiece(smooth[k], k == 0, k + 1 == smooth.size());
    for (const Node& n : nodes_) out_.planes.push_back(affineInIndex(grid_, n.t, n.r));
    out_.pieces.insert(out_.pieces.end(), caps_.begin(), caps_.end());
    for (const RodPiece& p : out_.pieces)
      if (!p.box.empty()) out_.box.expand(p.box);
    return std::move(out_);
  }

 private:
  static constexpr int kMaxRefinement = 24;

  // The segments of one smooth piece, then the half-spaces beyond its two end planes (the caps).
  void cutSmoothPiece(const geometry::SmoothPiece& sp, bool firstOfRod, bool lastOfRod) {
    const std::vector<double>& u = rod_.sampleParameters();
    const geometry::BSplineField& modulus = rod_.modulus();
    nodes_.push_back(node(rod_, u[sp.firstSample]));
    const std::size_t firstPlane = nodes_.size() - 1;
    for (std::size_t s = sp.firstSample + 1; s <= sp.lastSample; ++s) {
      const Node a = nodes_.back();
      refine(a, node(rod_, u[s], sp.endFromBelow && s == sp.lastSample), 0);
    }
    // E at the rod's ends as the field's own domain ends (it may differ from the centerline's by round-off).
    addCap(firstPlane, false, static_cast<float>(firstOfRod ? modulus.value(modulus.domainBegin()) : modulus.value(sp.begin)));
    addCap(nodes_.size() - 1, true, static_cast<float>(lastOfRod ? modulus.value(modulus.domainEnd()) : modulus.value(sp.end)));
  }

  void refine(const Node& a, const Node& b, int depth) {
    if (interrupted_ && ++steps_ % 256 == 0 && interrupted_())
      throw Interrupted("rasterizer: interrupted while cutting rod '" + rod_.name() + "' into pieces");
    RodPiece piece;
    const Measurement m = measure(rod_, a, b, piece);
    const bool modulusAccurate = m.modulusError <= modulusTolerance(a, b);
    const bool accurate = m.valid && m.coordinateError <= kCoordinateTolerance && modulusAccurate;
    // A piece accurate with the full estimate's terms only is split where halves cost less (even if
    // they need the terms too).
    const bool kept = accurate && !(needsFullEstimate(piece) && halvesCostLess(a, b));
    // Splitting stops at the depth limit and when the rod's budget is spent, and for the geometry at
    // pieces shorter than the voxels can tell apart (where the sections fold over, or round-off far
    // from the origin dominates, it would not converge); E converges away from its rare jumps, which
    // the depth limit confines. What is left inaccurate keeps its measured bound or goes exact.
    const bool geometryAccurate = m.valid && m.coordinateError <= kCoordinateTolerance;
    const double length = (b.r - a.r).norm() + m.chordDeviation;
    if (!kept && depth < kMaxRefinement && (geometryAccurate || length >= minLength_) && planned_ < budget_ && b.u > a.u) {
      ++planned_;
      refine(a, m.mid, depth + 1);
      refine(m.mid, b, depth + 1);
      return;
    }
    if (m.valid && modulusAccurate) addSwept(a, b, m, piece);
    else addExact(a, b, m);
  }

  // Whether two halves of the piece from a to b cost the voxel loop less than the whole piece with the
  // full estimate (needsFullEstimate: fifteen more vector operations for each quad of four voxels, about
  // a fifth more). The whole piece pays that on all its voxels, A L / (dx dy dz) for a section of area A
  // and a chord of length L; a cut adds the rows its plane crosses, the section seen along x,
  // |t_x| A / (dy dz) with t the chord's direction, each with a row's set-up and on average half a quad
  // unused. With ~40 instructions a row's set-up and ~70 a quad, halves cost less once
  // L / dx > kHalvesRowRatio |t_x|, where kHalvesRowRatio = 4 (40 + 70 / 2) / 15 is about 20. The model
  // leaves out what a piece costs whatever its length (its set-up in each block and layer), which favours
  // longer pieces.
  // Measured (callgrind, bench/README.md): 30 keeps the spring's instructions (3,254.5 M against 3,418.6 M
  // with every piece whole and 3,251.9 M before the full estimate's terms) and nearly all of the curved
  // lattice's gain (a band: 839.3 M against 835.4 M with every piece whole, 1,013.7 M before); 15 and 60
  // did worse.
  bool halvesCostLess(const Node& a, const Node& b) const {
    constexpr double kHalvesRowRatio = 30.0;
    const Vec3 chord = b.r - a.r;
    return chord.squaredNorm() > kHalvesRowRatio * grid_.voxelSize.x() * std::abs(chord.x());
  }

  void addSwept(const Node& a, const Node& b, const Measurement& m, RodPiece piece) {
    piece.kind = RodPiece::Kind::Swept;
    piece.x1Begin = affineInIndex(grid_, a.d1, a.r);
    piece.x2Begin = affineInIndex(grid_, a.d2, a.r);
    piece.x1End = affineInIndex(grid_, b.d1, b.r);
    piece.x2End = affineInIndex(grid_, b.d2, b.r);
    piece.normalizedRadiusErrorBound = gaugeFactor_ * m.coordinateError * inverseMinHalf_ + 1e-12;
    // A voxel the piece owns is within the bounding radius of a centerline point of the piece, and
    // that point within the chord deviation of the chord; those decided exactly lie up to the
    // coordinate bound further out.
    finish(a, b, m.chordDeviation + m.coordinateError, piece);
  }

  void addExact(const Node& a, const Node& b, const Measurement& m) {
    RodPiece piece;
    piece.kind = RodPiece::Kind::Exact;
    piece.normalizedRadiusErrorBound = std::numeric_limits<double>::infinity();
    // Every point of the piece's centerline is within its deviation bound of the chord, or (where
    // the curve folds back) within half its polyline length of the chord's ends.
    finish(a, b, std::max(m.chordDeviation, 0.5 * ((b.r - a.r).norm() + 2.0 * m.chordDeviation)), piece);
  }

  // Places the piece between the last plane and b's, and makes b's plane the last.
  void finish(const Node& a, const Node& b, double slack, RodPiece& piece) {
    piece.plane = static_cast<int>(nodes_.size()) - 1;
    const Vec3 chord = b.r - a.r;
    piece.axisPoint = a.r;
    piece.axisDirection = chord.norm() > 0.0 ? Vec3(chord.normalized()) : a.t;
    piece.reach = boundingRadius_ + slack + 1e-7;
    piece.box = indexBox(grid_, a.r.cwiseMin(b.r).array() - piece.reach, a.r.cwiseMax(b.r).array() + piece.reach);
    out_.pieces.push_back(piece);
    nodes_.push_back(b);
  }

  void addCap(std::size_t plane, bool atEnd, float capModulus) {
    const Node& n = nodes_[plane];
    RodPiece cap;
    cap.kind = atEnd ? RodPiece::Kind::EndCap : RodPiece::Kind::BeginCap;
    cap.plane = static_cast<int>(plane);
    for (int k = 0; k < 3; ++k) cap.capOffset[k] = affineInIndex(grid_, Vec3::Unit(k), n.r);
    cap.capModulus = capModulus;
    cap.axisPoint = n.r;
    cap.axisDirection = n.t;
    cap.reach = capReach_;
    cap.box = indexBox(grid_, n.r.array() - capReach_, n.r.array() + capReach_);
    caps_.push_back(cap);
  }

  const geometry::Rod& rod_;
  const PrinterGrid& grid_;
  const std::function<bool()>& interrupted_;
  const double minLength_;
  const std::size_t budget_;
  std::size_t planned_;  // pieces so far if no more splits came: the segments and the caps
  std::size_t steps_ = 0;
  double boundingRadius_ = 0.0, inverseMinHalf_ = 0.0, gaugeFactor_ = 0.0, capReach_ = 0.0;
  RodPieces out_;
  std::vector<Node> nodes_;  // one per plane
  std::vector<RodPiece> caps_;
};

}  // namespace

RodPieces buildRodPieces(const geometry::Rod& rod, const PrinterGrid& grid, const std::function<bool()>& interrupted) {
  return PieceBuilder(rod, grid, interrupted).build();
}

}  // namespace rodfab::voxel::detail
