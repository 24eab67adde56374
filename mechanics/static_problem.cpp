#include "mechanics/cosserat_point.hpp"
#include "mechanics/mechanics.hpp"
#include "mechanics/section_properties.hpp"

#include <Eigen/Geometry>
#include <Eigen/SparseLU>
#include <unsupported/Eigen/AutoDiff>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numeric>
#include <sstream>

namespace rodfab::mechanics {

using namespace detail;
using geometry::Vec3;
using Eigen::Vector3d;
using Eigen::Vector4d;

namespace {

template <int N> using Dual = Eigen::AutoDiffScalar<Eigen::Matrix<double, N, 1>>;

std::string format(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

std::string format(const Vector3d& v) { return "[" + format(v.x()) + ", " + format(v.y()) + ", " + format(v.z()) + "]"; }

// Non-zero (rational) basis functions and their first two derivatives at one parameter.
struct Basis {
  int first = 0;  // index of the first non-zero function
  int count = 0;  // degree + 1
  std::array<double, geometry::kMaxDegree + 1> value{}, d1{}, d2{};
};

Basis rationalBasis(const geometry::NurbsCurve& curve, double u) {
  const int p = curve.degree();
  const int n = static_cast<int>(curve.points().size());
  const int span = geometry::findKnotSpan(curve.knots(), p, n, u);
  geometry::BasisDerivatives ders;
  geometry::basisFunctionDerivatives(curve.knots(), p, span, u, 2, ders);
  Basis b;
  b.first = span - p;
  b.count = p + 1;
  if (!curve.isRational()) {
    for (int i = 0; i <= p; ++i) b.value[i] = ders[0][i], b.d1[i] = ders[1][i], b.d2[i] = ders[2][i];
    return b;
  }
  // R_i = N_i w_i / W and its derivatives by the quotient rule.
  double W = 0, dW = 0, ddW = 0;
  for (int i = 0; i <= p; ++i) {
    const double w = curve.weights()[b.first + i];
    W += ders[0][i] * w, dW += ders[1][i] * w, ddW += ders[2][i] * w;
  }
  for (int i = 0; i <= p; ++i) {
    const double w = curve.weights()[b.first + i];
    b.value[i] = ders[0][i] * w / W;
    b.d1[i] = (ders[1][i] * w - b.value[i] * dW) / W;
    b.d2[i] = (ders[2][i] * w - 2.0 * b.d1[i] * dW - b.value[i] * ddW) / W;
  }
  return b;
}

struct EndId {
  int rod = 0;
  int end = 0;  // 0 start, 1 end
  bool operator<(const EndId& o) const { return rod != o.rod ? rod < o.rod : end < o.end; }
  bool operator==(const EndId& o) const { return rod == o.rod && end == o.end; }
};

enum class Hold { None, Pinned, Clamped };

struct Node {
  std::vector<EndId> ends;  // the first end's slot carries the balance / support rows
  Hold hold = Hold::None;
  std::string supportPath;
  Vector3d displacement = Vector3d::Zero(), rotation = Vector3d::Zero();
  Vector3d force = Vector3d::Zero(), moment = Vector3d::Zero();
  // Reference data: the first end's position and unit quaternion; per further end its offset from
  // the first end and the relative rotation conj(q_first) q_end to keep.
  Vector3d position0;
  Vector4d quaternion0;
  std::vector<Vector3d> offsets0;
  std::vector<Vector4d> relative0;
};

struct RodModel {
  std::string name, path;
  geometry::NurbsCurve curve;  // refined; its control points are the reference positions
  int degree = 0, count = 0;
  std::size_t offset = 0;      // first unknown
  std::vector<double> tau;     // Greville abscissae
  std::vector<Basis> basis;    // at tau
  std::vector<PointConstants> constants;  // at tau
  double length = 0.0, forceScale = 1.0, momentScale = 1.0;
  const geometry::Rod* source = nullptr;

  std::size_t row(int j) const { return offset + 7 * static_cast<std::size_t>(j); }
  int point(int end) const { return end == 0 ? 0 : count - 1; }
};

Vector4d unitQuaternion(const geometry::Frame& f) {
  Eigen::Matrix3d m;
  m.col(0) = f.d1, m.col(1) = f.d2, m.col(2) = f.d3;
  const Eigen::Quaterniond q(m);
  return Vector4d(q.w(), q.x(), q.y(), q.z()).normalized();
}

// Interpolated values of the local state at one parameter from x.
struct LocalState {
  Vector3d r, dr, ddr;
  Vector4d q, dq, ddq;
};

LocalState localState(const RodModel& rod, const Basis& b, const Eigen::VectorXd& x) {
  LocalState s;
  s.r.setZero(), s.dr.setZero(), s.ddr.setZero(), s.q.setZero(), s.dq.setZero(), s.ddq.setZero();
  for (int k = 0; k < b.count; ++k) {
    const std::size_t at = rod.offset + 7 * static_cast<std::size_t>(b.first + k);
    const Vector3d r = x.segment<3>(at);
    const Vector4d q = x.segment<4>(at + 3);
    s.r += b.value[k] * r, s.dr += b.d1[k] * r, s.ddr += b.d2[k] * r;
    s.q += b.value[k] * q, s.dq += b.d1[k] * q, s.ddq += b.d2[k] * q;
  }
  return s;
}

// Dense rows with their columns, added into the global Jacobian.
struct Block {
  std::vector<std::size_t> rows, cols;
  Eigen::MatrixXd values;
};

// Columns of the control points a basis touches, 7 per point.
void appendColumns(const RodModel& rod, const Basis& b, std::vector<std::size_t>& cols) {
  for (int k = 0; k < b.count; ++k)
    for (int c = 0; c < 7; ++c) cols.push_back(rod.offset + 7 * static_cast<std::size_t>(b.first + k) + c);
}

// Chain rule from derivatives with respect to an end's (r, r', q, q') (14 columns) to its control points.
void chainEnd(const Basis& b, const Eigen::Matrix<double, Eigen::Dynamic, 14>& d, Eigen::Ref<Eigen::MatrixXd> out) {
  for (int k = 0; k < b.count; ++k) {
    out.middleCols<3>(7 * k) += d.middleCols<3>(0) * b.value[k] + d.middleCols<3>(3) * b.d1[k];
    out.middleCols<4>(7 * k + 3) += d.middleCols<4>(6) * b.value[k] + d.middleCols<4>(10) * b.d1[k];
  }
}

}  // namespace

// One block of rows: an interior collocation point of a rod, or a node (rod < 0, point = node index).
struct WorkItem {
  int rod, point;
};

struct StaticProblem::Model {
  std::string source;
  std::vector<RodModel> rods;
  std::vector<Node> nodes;
  std::vector<WorkItem> items;  // every interior collocation point, then every node
  std::size_t unknowns = 0, joints = 0, supports = 0;
  double size = 1.0;  // structure's bounding-box diagonal
  Eigen::VectorXd reference;

  const RodModel& rodOf(const EndId& e) const { return rods[e.rod]; }
  const Basis& endBasis(const EndId& e) const { const RodModel& r = rods[e.rod]; return r.basis[r.point(e.end)]; }
  const PointConstants& endConstants(const EndId& e) const { const RodModel& r = rods[e.rod]; return r.constants[r.point(e.end)]; }

  [[noreturn]] void fail(const std::string& path, const std::string& message) const {
    throw MechanicsError(source + ": " + (path.empty() ? "" : path + ": ") + message);
  }

  void buildRod(const geometry::RodStructure& structure, std::size_t index, const Discretization& discretization);
  void buildNodes(const geometry::RodStructure& structure);
  EndId resolve(const geometry::RodEndRef& ref, const geometry::RodStructure& structure) const;
  void interiorBlock(const RodModel& rod, int j, const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                     Block* block) const;
  void nodeBlock(const Node& node, const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual, Block* block) const;
};

void StaticProblem::Model::buildRod(const geometry::RodStructure& structure, std::size_t index,
                                    const Discretization& discretization) {
  const geometry::Rod& src = structure.rods[index];
  RodModel rod;
  rod.name = src.name();
  rod.path = "rods[" + std::to_string(index) + "]";
  rod.source = &src;
  const geometry::NurbsCurve& c0 = src.centerline();
  const bool rebuild = discretization.degree > 0 && (discretization.degree != c0.degree() || discretization.spans > 0);
  const int p = rebuild ? discretization.degree : c0.degree();
  if (p > geometry::kMaxDegree) fail("", "degree " + std::to_string(p) + " is above the supported " + std::to_string(geometry::kMaxDegree));
  if (p < 2)
    fail(rod.path + ".centerline.degree", "the rod solver collocates second derivatives and needs degree >= 2 (even "
                                          "degrees converge best), got " + std::to_string(p));
  const auto& k0 = c0.knots();
  const std::size_t n0 = c0.points().size();
  const int q = c0.degree();
  for (int i = 1; i <= q; ++i)
    if (k0[i] != k0[0] || k0[n0 + q - i] != k0[n0 + q])
      fail(rod.path + ".centerline.knots", "the rod solver needs clamped (open) knot vectors, the first and last " +
                                               std::to_string(q + 1) + " knots equal, so the ends are collocation points");
  for (std::size_t i = q + 1; i < n0;) {
    std::size_t m = 1;
    while (i + m < n0 && k0[i + m] == k0[i]) ++m;
    if (m >= static_cast<std::size_t>(q))
      fail(rod.path + ".centerline.knots[" + std::to_string(i) + "]",
           "knot " + format(k0[i]) + " repeated " + std::to_string(m) + " times makes a kink the collocation cannot "
           "resolve; split the rod there (rods joined at a kink are coupled rigidly)");
    i += m;
  }
  if (rebuild) {
    // A degree-p rod needs a few spans to bend at all; fewer than 8 is rarely what anyone wants.
    const int spans = discretization.spans > 0
                          ? discretization.spans
                          : std::max(8, static_cast<int>(c0.breakpoints().size() - 1) * (discretization.refine + 1));
    std::vector<double> knots(p + 1, c0.domainBegin());
    for (int i = 1; i < spans; ++i) knots.push_back(c0.domainBegin() + (c0.domainEnd() - c0.domainBegin()) * i / spans);
    knots.insert(knots.end(), p + 1, c0.domainEnd());
    // Placeholder control points; the interpolation below replaces them.
    rod.curve = geometry::NurbsCurve(p, std::move(knots), std::vector<Vec3>(spans + p, Vec3::Zero()));
  } else {
    rod.curve = c0.refined(discretization.refine);
  }
  rod.degree = p;
  rod.count = static_cast<int>(rod.curve.points().size());
  if (rod.count < 3) fail(rod.path + ".centerline.points", "needs at least 3 control points");
  rod.length = src.length();

  const auto& knots = rod.curve.knots();
  rod.tau.resize(rod.count);
  for (int j = 0; j < rod.count; ++j) {
    double sum = 0;
    for (int i = 1; i <= p; ++i) sum += knots[j + i];
    rod.tau[j] = sum / p;
  }
  rod.tau.front() = rod.curve.domainBegin();
  rod.tau.back() = rod.curve.domainEnd();

  // E must be differentiable where it is collocated (n' contains E').
  const geometry::BSplineField& e = src.modulus();
  if (!e.isConstant()) {
    const auto& ek = e.knots();
    const double scale = std::max(1.0, std::abs(e.domainEnd() - e.domainBegin()));
    for (std::size_t i = e.degree() + 1; i < e.values().size();) {
      std::size_t m = 1;
      while (i + m < e.values().size() && ek[i + m] == ek[i]) ++m;
      if (m >= static_cast<std::size_t>(e.degree()))
        for (double t : rod.tau)
          if (std::abs(t - ek[i]) <= 1e-12 * scale)
            fail(rod.path + ".modulus.knots[" + std::to_string(i) + "]",
                 "E(s) has a kink at u = " + format(ek[i]) + ", which is a collocation point, where the solver needs E'(s); "
                 "raise the field's degree or move the knot");
      i += m;
    }
  }

  const geometry::MechanicsSpec& spec = structure.mechanics;
  double nu = spec.poissonRatio;
  std::optional<double> shear = spec.shearFactor, torsion;
  for (const auto& over : spec.rods)
    if (over.rod == rod.name) {
      if (over.poissonRatio) nu = *over.poissonRatio;
      if (over.shearFactor) shear = *over.shearFactor;
      torsion = over.torsionConstant;
    }
  SectionProperties props = sectionProperties(src.section(), nu);
  if (shear) props.shearFactor = *shear;
  if (torsion) props.torsionConstant = *torsion;
  const double G = 1.0 / (2.0 * (1.0 + nu));  // per unit E
  const Vector3d shearExtension(props.shearFactor * G * props.area, props.shearFactor * G * props.area, props.area);
  const Vector3d bendingTorsion(props.inertia1, props.inertia2, G * props.torsionConstant);
  Vector3d distributed = Vector3d::Zero();
  for (const auto& d : spec.distributedLoads)
    if (d.rod == rod.name) distributed += d.force;

  // Reference quaternions (and, when rebuilt, positions): interpolate the design's frames at the
  // collocation points, so the unit-norm conditions hold exactly in the reference state.
  rod.basis.resize(rod.count);
  for (int j = 0; j < rod.count; ++j) rod.basis[j] = rationalBasis(rod.curve, rod.tau[j]);
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::MatrixXd samples(rod.count, 7);
  Vector4d previous = Vector4d::Zero();
  for (int j = 0; j < rod.count; ++j) {
    for (int k = 0; k < rod.basis[j].count; ++k) entries.emplace_back(j, rod.basis[j].first + k, rod.basis[j].value[k]);
    Vector4d q = unitQuaternion(src.frame().at(c0, rod.tau[j]));
    if (j > 0 && q.dot(previous) < 0) q = -q;
    samples.block<1, 3>(j, 0) = c0.point(rod.tau[j]).transpose();
    samples.block<1, 4>(j, 3) = q.transpose();
    previous = q;
  }
  Eigen::SparseMatrix<double> collocation(rod.count, rod.count);
  collocation.setFromTriplets(entries.begin(), entries.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(collocation);
  if (lu.info() != Eigen::Success) fail(rod.path + ".centerline", "the collocation matrix is singular");
  const Eigen::MatrixXd interpolated = lu.solve(samples);
  if (rebuild) {
    std::vector<Vec3> points(rod.count);
    for (int i = 0; i < rod.count; ++i) points[i] = interpolated.block<1, 3>(i, 0).transpose();
    rod.curve = geometry::NurbsCurve(p, rod.curve.knots(), std::move(points));
  }
  const Eigen::MatrixXd quaternions = interpolated.rightCols<4>();

  rod.offset = unknowns;
  unknowns += 7 * static_cast<std::size_t>(rod.count);
  reference.conservativeResize(static_cast<Eigen::Index>(unknowns));
  for (int i = 0; i < rod.count; ++i) {
    reference.segment<3>(rod.offset + 7 * i) = rod.curve.points()[i];
    reference.segment<4>(rod.offset + 7 * i + 3) = quaternions.row(i).transpose();
  }

  double eMax = 0;
  rod.constants.resize(rod.count);
  for (int j = 0; j < rod.count; ++j) {
    const LocalState s = localState(rod, rod.basis[j], reference);
    const StrainMeasures<double> sm = strainMeasures<double>(s.dr, s.ddr, s.q, s.dq, s.ddq);
    PointConstants& c = rod.constants[j];
    c.J0 = s.dr.norm();
    if (!(c.J0 > 0)) fail(rod.path + ".centerline", "the centerline's derivative vanishes at u = " + format(rod.tau[j]));
    c.dJ0 = s.dr.dot(s.ddr) / c.J0;
    c.gamma0 = sm.gamma, c.dGamma0 = sm.dGamma, c.curvature0 = sm.curvature, c.dCurvature0 = sm.dCurvature;
    c.E = e.value(rod.tau[j]);
    c.dE = e.isConstant() ? 0.0 : e.derivative(rod.tau[j]);
    c.shearExtension = shearExtension;
    c.bendingTorsion = bendingTorsion;
    c.distributedForce = distributed;
    eMax = std::max(eMax, c.E);
  }
  // Residual rows in units of the rod's bending: E I / L^2 for forces, E I / L for moments. A scale
  // by E A would hide the loads that bend slender rods (E A L^2 / E I = (L / r)^2 is 1e6 and more).
  const double bending = eMax * std::max(props.inertia1, props.inertia2);
  rod.forceScale = bending / (rod.length * rod.length);
  rod.momentScale = bending / rod.length;
  rods.push_back(std::move(rod));
}

EndId StaticProblem::Model::resolve(const geometry::RodEndRef& ref, const geometry::RodStructure& structure) const {
  if (!ref.point) {
    for (std::size_t i = 0; i < structure.rods.size(); ++i)
      if (structure.rods[i].name() == ref.rod) return {static_cast<int>(i), ref.end == geometry::RodEnd::Start ? 0 : 1};
    fail(ref.path + ".rod", "no rod is named \"" + ref.rod + "\"");
  }
  EndId best;
  double bestDistance = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < rods.size(); ++i)
    for (int end = 0; end < 2; ++end) {
      const Vec3& p = end == 0 ? rods[i].curve.points().front() : rods[i].curve.points().back();
      const double d = (p - *ref.point).norm();
      if (d < bestDistance) bestDistance = d, best = {static_cast<int>(i), end};
    }
  if (bestDistance > structure.mechanics.jointTolerance)
    fail(ref.path + ".point", "no rod end lies within joint_tolerance (" + format(structure.mechanics.jointTolerance) +
                                  " mm) of " + format(*ref.point) + "; the nearest is the " + (best.end ? "end" : "start") +
                                  " of rod \"" + rods[best.rod].name + "\", " + format(bestDistance) +
                                  " mm away (loads and supports act on rod ends and joints)");
  return best;
}

void StaticProblem::Model::buildNodes(const geometry::RodStructure& structure) {
  const geometry::MechanicsSpec& spec = structure.mechanics;
  const int endCount = static_cast<int>(2 * rods.size());
  auto endIndex = [](const EndId& e) { return 2 * e.rod + e.end; };
  auto endPoint = [&](const EndId& e) -> const Vec3& {
    return e.end == 0 ? rods[e.rod].curve.points().front() : rods[e.rod].curve.points().back();
  };
  // Union-find over rod ends.
  std::vector<int> parent(endCount);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  auto unite = [&](int a, int b) {
    a = find(a), b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  };
  if (spec.inferJoints) {
    // Sort ends by x so only neighbours within the tolerance are compared.
    std::vector<int> order(endCount);
    std::iota(order.begin(), order.end(), 0);
    auto at = [&](int i) -> const Vec3& { return endPoint({i / 2, i % 2}); };
    std::sort(order.begin(), order.end(), [&](int a, int b) { return at(a).x() < at(b).x() || (at(a).x() == at(b).x() && a < b); });
    for (int a = 0; a < endCount; ++a)
      for (int b = a + 1; b < endCount && at(order[b]).x() - at(order[a]).x() <= spec.jointTolerance; ++b)
        if ((at(order[a]) - at(order[b])).norm() <= spec.jointTolerance) unite(order[a], order[b]);
  } else {
    std::map<int, std::string> listed;
    for (std::size_t j = 0; j < spec.joints.size(); ++j)
      for (std::size_t k = 0; k < spec.joints[j].size(); ++k) {
        const EndId e = resolve(spec.joints[j][k], structure);
        const std::string where = spec.joints[j][k].path;
        if (auto [it, fresh] = listed.emplace(endIndex(e), where); !fresh)
          fail(where, "this rod end is already in a joint (" + it->second + ")");
        unite(endIndex(resolve(spec.joints[j][0], structure)), endIndex(e));
      }
  }
  std::map<int, std::size_t> nodeOf;
  for (int i = 0; i < endCount; ++i) {
    const int root = find(i);
    auto [it, fresh] = nodeOf.emplace(root, nodes.size());
    if (fresh) nodes.emplace_back();
    nodes[it->second].ends.push_back({i / 2, i % 2});
  }
  for (const Node& node : nodes) joints += node.ends.size() > 1;

  for (const auto& s : spec.supports) {
    Node& node = nodes[nodeOf.at(find(endIndex(resolve(s.at, structure))))];
    if (node.hold != Hold::None)
      fail(s.at.path, "this rod end (or joint) already has a support (" + node.supportPath + ")");
    node.hold = s.kind == geometry::SupportKind::Clamped ? Hold::Clamped : Hold::Pinned;
    node.supportPath = s.at.path;
    node.displacement = s.displacement;
    node.rotation = s.rotation;
    ++supports;
  }
  for (const auto& l : spec.loads) {
    Node& node = nodes[nodeOf.at(find(endIndex(resolve(l.at, structure))))];
    node.force += l.force;
    node.moment += l.moment;
  }
  if (supports == 0)
    fail("mechanics.supports", "no support: the structure could move as a rigid body; clamp or pin at least one rod end");

  // Every connected part of the structure needs a support of its own: joining each rod's two ends
  // in the same union-find turns the joints into connected parts.
  for (std::size_t r = 0; r < rods.size(); ++r) unite(static_cast<int>(2 * r), static_cast<int>(2 * r + 1));
  std::vector<bool> held(endCount, false);
  for (const Node& node : nodes)
    if (node.hold != Hold::None) held[find(endIndex(node.ends.front()))] = true;
  for (std::size_t r = 0; r < rods.size(); ++r)
    if (!held[find(static_cast<int>(2 * r))])
      fail("mechanics.supports", "rod \"" + rods[r].name + "\" belongs to a part of the structure without any support "
                                 "(it is not joined to a supported rod); support it or join it");

  for (Node& node : nodes) {
    const EndId first = node.ends.front();
    const LocalState s0 = localState(rodOf(first), endBasis(first), reference);
    node.position0 = s0.r;
    node.quaternion0 = s0.q.normalized();
    for (std::size_t i = 1; i < node.ends.size(); ++i) {
      const LocalState s = localState(rodOf(node.ends[i]), endBasis(node.ends[i]), reference);
      node.offsets0.push_back(s.r - s0.r);
      const Vector4d conj0(node.quaternion0[0], -node.quaternion0[1], -node.quaternion0[2], -node.quaternion0[3]);
      node.relative0.push_back(quaternionProduct<double>(conj0, s.q.normalized()));
    }
  }
}

void StaticProblem::Model::interiorBlock(const RodModel& rod, int j, const Eigen::VectorXd& x, double load,
                                         Eigen::VectorXd& residual, Block* block) const {
  const Basis& b = rod.basis[j];
  const LocalState s = localState(rod, b, x);
  const PointConstants& c = rod.constants[j];
  Eigen::Matrix<double, 7, 1> scale;
  const double forceRow = rod.length / (c.J0 * rod.forceScale), momentRow = rod.length / (c.J0 * rod.momentScale);
  scale << forceRow, forceRow, forceRow, momentRow, momentRow, momentRow, 1.0;
  const std::size_t row = rod.row(j);
  if (!block) {
    residual.segment<7>(row) = equilibriumResidual<double>(s.dr, s.ddr, s.q, s.dq, s.ddq, c, load).cwiseProduct(scale);
    return;
  }
  using D = Dual<18>;
  V3<D> dr, ddr;
  V4<D> q, dq, ddq;
  for (int i = 0; i < 3; ++i) dr[i] = D(s.dr[i], 18, i), ddr[i] = D(s.ddr[i], 18, 3 + i);
  for (int i = 0; i < 4; ++i) q[i] = D(s.q[i], 18, 6 + i), dq[i] = D(s.dq[i], 18, 10 + i), ddq[i] = D(s.ddq[i], 18, 14 + i);
  const Eigen::Matrix<D, 7, 1> f = equilibriumResidual<D>(dr, ddr, q, dq, ddq, c, load);
  Eigen::Matrix<double, 7, 18> d;
  for (int i = 0; i < 7; ++i) {
    residual[row + i] = f[i].value() * scale[i];
    d.row(i) = f[i].derivatives().transpose() * scale[i];
  }
  block->rows.resize(7);
  std::iota(block->rows.begin(), block->rows.end(), row);
  block->cols.clear();
  appendColumns(rod, b, block->cols);
  block->values.setZero(7, 7 * b.count);
  for (int k = 0; k < b.count; ++k) {
    block->values.middleCols<3>(7 * k) = d.middleCols<3>(0) * b.d1[k] + d.middleCols<3>(3) * b.d2[k];
    block->values.middleCols<4>(7 * k + 3) =
        d.middleCols<4>(6) * b.value[k] + d.middleCols<4>(10) * b.d1[k] + d.middleCols<4>(14) * b.d2[k];
  }
}

void StaticProblem::Model::nodeBlock(const Node& node, const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                                     Block* block) const {
  const std::size_t k = node.ends.size();
  // Per end: values and derivatives with respect to (r, r', q, q') of the end's force and moment.
  struct EndData {
    LocalState s;
    Vector3d n, m;
    Eigen::Matrix<double, 3, 14> dn, dm;
    std::size_t col = 0;  // first column of this end in the block
  };
  std::vector<EndData> ends(k);
  std::size_t cols = 0;
  for (std::size_t i = 0; i < k; ++i) {
    const EndId& e = node.ends[i];
    EndData& d = ends[i];
    d.s = localState(rodOf(e), endBasis(e), x);
    d.col = cols;
    cols += 7 * static_cast<std::size_t>(endBasis(e).count);
    const PointConstants& c = endConstants(e);
    if (!block) {
      const StrainMeasures<double> sm = strainMeasures<double>(d.s.dr, Vector3d::Zero(), d.s.q, d.s.dq, Vector4d::Zero());
      stressResultants(sm, c, d.n, d.m);
      continue;
    }
    using D = Dual<11>;
    V3<D> dr;
    V4<D> q, dq;
    for (int j = 0; j < 3; ++j) dr[j] = D(d.s.dr[j], 11, j);
    for (int j = 0; j < 4; ++j) q[j] = D(d.s.q[j], 11, 3 + j), dq[j] = D(d.s.dq[j], 11, 7 + j);
    const StrainMeasures<D> sm = strainMeasures<D>(dr, V3<D>::Zero(), q, dq, V4<D>::Zero());
    V3<D> n, m;
    stressResultants(sm, c, n, m);
    d.dn.setZero(), d.dm.setZero();
    for (int j = 0; j < 3; ++j) {
      d.n[j] = n[j].value(), d.m[j] = m[j].value();
      d.dn.block<1, 11>(j, 3) = n[j].derivatives().transpose();
      d.dm.block<1, 11>(j, 3) = m[j].derivatives().transpose();
    }
  }
  const RodModel& firstRod = rodOf(node.ends[0]);
  const double forceRow = 1.0 / firstRod.forceScale, momentRow = 1.0 / firstRod.momentScale;
  const double positionRow = 1.0 / firstRod.length;
  // Rows of every end's slot; derivative rows with respect to the 14 end values of each end.
  const std::size_t rows = 7 * k;
  Eigen::VectorXd f(rows);
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, 14>> dEnd(k, Eigen::Matrix<double, Eigen::Dynamic, 14>::Zero(rows, 14));
  const EndData& e0 = ends[0];
  auto sign = [&](std::size_t i) { return node.ends[i].end == 0 ? 1.0 : -1.0; };  // + n(0) at a start, - n(L) at an end

  if (node.hold != Hold::None) {
    f.segment<3>(0) = (e0.s.r - node.position0 - load * node.displacement) * positionRow;
    dEnd[0].block<3, 3>(0, 0) = Eigen::Matrix3d::Identity() * positionRow;
  } else {
    Vector3d sum = load * node.force;
    for (std::size_t i = 0; i < k; ++i) {
      sum += sign(i) * ends[i].n;
      if (block) dEnd[i].block<3, 14>(0, 0) += sign(i) * ends[i].dn * forceRow;
    }
    f.segment<3>(0) = sum * forceRow;
  }
  if (node.hold == Hold::Clamped) {
    // vec(conj(q_target) q) = 0 with q_target the reference end rotation turned by load * rotation.
    const double angle = load * node.rotation.norm();
    Vector4d turn(1, 0, 0, 0);
    if (angle > 0) turn << std::cos(angle / 2), std::sin(angle / 2) * node.rotation.normalized();
    const Vector4d target = quaternionProduct<double>(turn, node.quaternion0);
    f.segment<3>(3) = conjugateProductVector<double>(target, e0.s.q);
    for (int c = 0; c < 4; ++c) dEnd[0].block<3, 1>(3, 6 + c) = conjugateProductVector<double>(target, Vector4d::Unit(c));
  } else {
    Vector3d sum = load * node.moment;
    for (std::size_t i = 0; i < k; ++i) {
      const EndData& d = ends[i];
      const Vector3d arm = d.s.r - e0.s.r;
      sum += sign(i) * (d.m + arm.cross(d.n));
      if (!block) continue;
      Eigen::Matrix3d armCross, nCross;
      armCross << 0, -arm.z(), arm.y(), arm.z(), 0, -arm.x(), -arm.y(), arm.x(), 0;
      nCross << 0, -d.n.z(), d.n.y(), d.n.z(), 0, -d.n.x(), -d.n.y(), d.n.x(), 0;
      dEnd[i].block<3, 14>(3, 0) += sign(i) * momentRow * (d.dm + armCross * d.dn);
      // arm x n = -n x arm: d(arm) = dr_i - dr_0.
      dEnd[i].block<3, 3>(3, 0) -= sign(i) * momentRow * nCross;
      dEnd[0].block<3, 3>(3, 0) += sign(i) * momentRow * nCross;
    }
    f.segment<3>(3) = sum * momentRow;
  }
  f[6] = e0.s.q.squaredNorm() - 1.0;
  dEnd[0].block<1, 4>(6, 6) = 2.0 * e0.s.q.transpose();

  for (std::size_t i = 1; i < k; ++i) {
    const EndData& d = ends[i];
    const std::size_t r0 = 7 * i;
    f.segment<3>(r0) = (d.s.r - e0.s.r - node.offsets0[i - 1]) * positionRow;
    dEnd[i].block<3, 3>(r0, 0) += Eigen::Matrix3d::Identity() * positionRow;
    dEnd[0].block<3, 3>(r0, 0) -= Eigen::Matrix3d::Identity() * positionRow;
    // vec(conj(c) conj(q_0) q_i) = vec(conj(q_0 c) q_i) = 0 keeps the relative rotation c.
    using D = Dual<8>;
    V4<D> q0, qi;
    for (int j = 0; j < 4; ++j) q0[j] = D(e0.s.q[j], 8, j), qi[j] = D(d.s.q[j], 8, 4 + j);
    const V3<D> g = conjugateProductVector<D>(quaternionProduct<D>(q0, node.relative0[i - 1].cast<D>()), qi);
    for (int j = 0; j < 3; ++j) {
      f[r0 + 3 + j] = g[j].value();
      dEnd[0].block<1, 4>(r0 + 3 + j, 6) += g[j].derivatives().head<4>().transpose();
      dEnd[i].block<1, 4>(r0 + 3 + j, 6) += g[j].derivatives().tail<4>().transpose();
    }
    f[r0 + 6] = d.s.q.squaredNorm() - 1.0;
    dEnd[i].block<1, 4>(r0 + 6, 6) = 2.0 * d.s.q.transpose();
  }

  for (std::size_t i = 0; i < k; ++i) residual.segment<7>(rodOf(node.ends[i]).row(rodOf(node.ends[i]).point(node.ends[i].end))) = f.segment<7>(7 * i);
  if (!block) return;
  block->rows.clear();
  for (std::size_t i = 0; i < k; ++i) {
    const std::size_t row = rodOf(node.ends[i]).row(rodOf(node.ends[i]).point(node.ends[i].end));
    for (int r = 0; r < 7; ++r) block->rows.push_back(row + r);
  }
  block->cols.clear();
  block->values.setZero(static_cast<Eigen::Index>(rows), static_cast<Eigen::Index>(cols));
  for (std::size_t i = 0; i < k; ++i) {
    appendColumns(rodOf(node.ends[i]), endBasis(node.ends[i]), block->cols);
    const Basis& b = endBasis(node.ends[i]);
    chainEnd(b, dEnd[i], block->values.middleCols(static_cast<Eigen::Index>(ends[i].col), 7 * b.count));
  }
}

StaticProblem::StaticProblem(const geometry::RodStructure& structure, const Discretization& discretization)
    : model_(std::make_unique<Model>()) {
  Model& m = *model_;
  m.source = structure.source;
  if (discretization.refine < 0 || discretization.spans < 0 || discretization.degree < 0)
    throw std::invalid_argument("StaticProblem: degree, refine and spans must be >= 0");
  if (!structure.mechanics.present)
    m.fail("mechanics", "the design has no \"mechanics\" block: give at least its supports (and loads) to simulate it");
  for (std::size_t i = 0; i < structure.rods.size(); ++i) m.buildRod(structure, i, discretization);
  m.size = std::max(1e-12, structure.bounds().diagonal().norm());
  m.buildNodes(structure);
  for (std::size_t r = 0; r < m.rods.size(); ++r)
    for (int j = 1; j + 1 < m.rods[r].count; ++j) m.items.push_back({static_cast<int>(r), j});
  for (std::size_t n = 0; n < m.nodes.size(); ++n) m.items.push_back({-1, static_cast<int>(n)});
}

StaticProblem::~StaticProblem() = default;
StaticProblem::StaticProblem(StaticProblem&&) noexcept = default;
StaticProblem& StaticProblem::operator=(StaticProblem&&) noexcept = default;

std::size_t StaticProblem::unknownCount() const { return model_->unknowns; }
std::size_t StaticProblem::rodCount() const { return model_->rods.size(); }
std::size_t StaticProblem::jointCount() const { return model_->joints; }
std::size_t StaticProblem::supportCount() const { return model_->supports; }
std::size_t StaticProblem::controlPointCount(std::size_t rod) const { return model_->rods.at(rod).count; }
const std::string& StaticProblem::source() const { return model_->source; }
const Eigen::VectorXd& StaticProblem::referenceState() const { return model_->reference; }

void StaticProblem::evaluate(const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                             Eigen::SparseMatrix<double>* jacobian) const {
  const Model& m = *model_;
  if (static_cast<std::size_t>(x.size()) != m.unknowns) throw std::invalid_argument("StaticProblem::evaluate: wrong state size");
  residual.resize(x.size());
  const std::vector<WorkItem>& items = m.items;
  std::vector<Block> blocks(jacobian ? items.size() : 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, items.size(), 64), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      Block* block = jacobian ? &blocks[i] : nullptr;
      if (items[i].rod >= 0) m.interiorBlock(m.rods[items[i].rod], items[i].point, x, load, residual, block);
      else m.nodeBlock(m.nodes[items[i].point], x, load, residual, block);
    }
  });
  if (!jacobian) return;
  std::size_t entries = 0;
  for (const Block& b : blocks) entries += static_cast<std::size_t>(b.values.size());
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(entries);
  for (const Block& b : blocks)
    for (std::size_t c = 0; c < b.cols.size(); ++c)
      for (std::size_t r = 0; r < b.rows.size(); ++r)
        triplets.emplace_back(static_cast<int>(b.rows[r]), static_cast<int>(b.cols[c]), b.values(r, c));
  jacobian->resize(x.size(), x.size());
  jacobian->setFromTriplets(triplets.begin(), triplets.end());
}

Eigen::Vector3d StaticProblem::position(const Eigen::VectorXd& x, std::size_t rod, double u) const {
  const RodModel& r = model_->rods.at(rod);
  return localState(r, rationalBasis(r.curve, u), x).r;
}

Eigen::Matrix3d StaticProblem::rotation(const Eigen::VectorXd& x, std::size_t rod, double u) const {
  const RodModel& r = model_->rods.at(rod);
  const Vector4d q = localState(r, rationalBasis(r.curve, u), x).q;
  return rotationNumerator<double>(q) / q.squaredNorm();
}

double StaticProblem::stepNorm(const Eigen::VectorXd& dx) const {
  double norm = 0;
  for (Eigen::Index i = 0; i < dx.size(); i += 7) {
    norm = std::max(norm, dx.segment<3>(i).cwiseAbs().maxCoeff() / model_->size);
    norm = std::max(norm, dx.segment<4>(i + 3).cwiseAbs().maxCoeff());
  }
  return norm;
}

geometry::RodStructure StaticProblem::deformedStructure(const Eigen::VectorXd& x) const {
  const Model& m = *model_;
  geometry::RodStructure out;
  out.source = m.source;
  for (const RodModel& rod : m.rods) {
    std::vector<Vec3> points(rod.count);
    std::vector<Vector4d> quaternions(rod.count);
    for (int i = 0; i < rod.count; ++i) {
      points[i] = x.segment<3>(rod.offset + 7 * i);
      // q(u) on the rational basis is sum N_i w_i q_i / W(u); the positive factor 1 / W does not
      // change the rotation, so the quaternion B-spline with control values w_i q_i is the same frame.
      const double w = rod.curve.isRational() ? rod.curve.weights()[i] : 1.0;
      quaternions[i] = w * x.segment<4>(rod.offset + 7 * i + 3);
    }
    geometry::NurbsCurve centerline(rod.degree, rod.curve.knots(), points, rod.curve.weights());
    geometry::QuaternionSpline orientation(rod.degree, rod.curve.knots(), quaternions);
    const geometry::Rod& src = *rod.source;
    out.rods.emplace_back(src.name(), std::move(centerline), src.section(), std::nullopt, std::move(orientation),
                          src.caps(), src.modulus());
  }
  return out;
}

}  // namespace rodfab::mechanics
