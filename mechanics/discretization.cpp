// Each rod on its solver basis: the (refined or rebuilt) curve, the collocation points, the
// reference state interpolating the design's centerline and frames, and the pointwise constants.
#include "mechanics/discrete_structure.hpp"
#include "mechanics/section_properties.hpp"

#include <Eigen/Geometry>
#include <Eigen/SparseLU>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace rodfab::mechanics::detail {

using geometry::Vec3;
using Eigen::Vector3d;
using Eigen::Vector4d;

std::string format(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

std::string format(const Vector3d& v) {
  std::string s = "[";  // built by appending: GCC 12 warns falsely (-Wrestrict) on "[" + std::string
  s.append(format(v.x())).append(", ").append(format(v.y())).append(", ").append(format(v.z())).append("]");
  return s;
}

void DiscreteStructure::fail(const std::string& path, const std::string& message) const {
  throw MechanicsError(source + ": " + (path.empty() ? "" : path + ": ") + message);
}

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

LocalState localState(const DiscreteRod& rod, const Basis& b, const Eigen::VectorXd& x) {
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

namespace {

Vector4d unitQuaternion(const geometry::Frame& f) {
  Eigen::Matrix3d m;
  m.col(0) = f.d1, m.col(1) = f.d2, m.col(2) = f.d3;
  const Eigen::Quaterniond q(m);
  return Vector4d(q.w(), q.x(), q.y(), q.z()).normalized();
}

// The design's centerline must have a clamped knot vector and no kinks inside; the solver's degree
// p must allow second derivatives.
void checkCenterline(const DiscreteStructure& s, const geometry::NurbsCurve& c0, int p, const std::string& path) {
  if (p > geometry::kMaxDegree) s.fail("", "degree " + std::to_string(p) + " is above the supported " + std::to_string(geometry::kMaxDegree));
  if (p < 2)
    s.fail(path + ".centerline.degree", "the rod solver collocates second derivatives and needs degree >= 2 (even "
                                        "degrees converge best), got " + std::to_string(p));
  const auto& k0 = c0.knots();
  const std::size_t n0 = c0.points().size();
  const int q = c0.degree();
  for (int i = 1; i <= q; ++i)
    if (k0[i] != k0[0] || k0[n0 + q - i] != k0[n0 + q])
      s.fail(path + ".centerline.knots", "the rod solver needs clamped (open) knot vectors, the first and last " +
                                             std::to_string(q + 1) + " knots equal, so the ends are collocation points");
  for (std::size_t i = q + 1; i < n0;) {
    std::size_t m = 1;
    while (i + m < n0 && k0[i + m] == k0[i]) ++m;
    if (m >= static_cast<std::size_t>(q))
      s.fail(path + ".centerline.knots[" + std::to_string(i) + "]",
             "knot " + format(k0[i]) + " repeated " + std::to_string(m) + " times makes a kink the collocation cannot "
             "resolve; split the rod there (rods joined at a kink are coupled rigidly)");
    i += m;
  }
}

// The solver's curve: the design's refined by knot insertion, or (rebuild) a uniform degree-p
// B-spline with placeholder control points that interpolateReference replaces.
geometry::NurbsCurve solverCurve(const geometry::NurbsCurve& c0, const Discretization& discretization, bool rebuild, int p) {
  if (!rebuild) return c0.refined(discretization.refine);
  // A degree-p rod needs a few spans to bend at all; fewer than 8 is rarely what anyone wants.
  const int spans = discretization.spans > 0
                        ? discretization.spans
                        : std::max(8, static_cast<int>(c0.breakpoints().size() - 1) * (discretization.refine + 1));
  std::vector<double> knots(p + 1, c0.domainBegin());
  for (int i = 1; i < spans; ++i) knots.push_back(c0.domainBegin() + (c0.domainEnd() - c0.domainBegin()) * i / spans);
  knots.insert(knots.end(), p + 1, c0.domainEnd());
  return geometry::NurbsCurve(p, std::move(knots), std::vector<Vec3>(spans + p, Vec3::Zero()));
}

// Greville abscissae, with the ends exactly at the domain's ends.
std::vector<double> grevilleAbscissae(const geometry::NurbsCurve& curve) {
  const int p = curve.degree(), count = static_cast<int>(curve.points().size());
  const auto& knots = curve.knots();
  std::vector<double> tau(count);
  for (int j = 0; j < count; ++j) {
    double sum = 0;
    for (int i = 1; i <= p; ++i) sum += knots[j + i];
    tau[j] = sum / p;
  }
  tau.front() = curve.domainBegin();
  tau.back() = curve.domainEnd();
  return tau;
}

// E must be differentiable where it is collocated (n' contains E').
void checkModulusKinks(const DiscreteStructure& s, const geometry::BSplineField& e, const std::vector<double>& tau,
                       const std::string& path) {
  if (e.isConstant()) return;
  const auto& ek = e.knots();
  const double scale = std::max(1.0, std::abs(e.domainEnd() - e.domainBegin()));
  for (std::size_t i = e.degree() + 1; i < e.values().size();) {
    std::size_t m = 1;
    while (i + m < e.values().size() && ek[i + m] == ek[i]) ++m;
    if (m >= static_cast<std::size_t>(e.degree()))
      for (double t : tau)
        if (std::abs(t - ek[i]) <= 1e-12 * scale)
          s.fail(path + ".modulus.knots[" + std::to_string(i) + "]",
                 "E(s) has a kink at u = " + format(ek[i]) + ", which is a collocation point, where the solver needs E'(s); "
                 "raise the field's degree or move the knot");
    i += m;
  }
}

// Section stiffness per unit E and the distributed load of one rod, with the design's overrides.
struct RodStiffness {
  Vector3d shearExtension;  // (k G A, k G A, A)
  Vector3d bendingTorsion;  // (I1, I2, G J)
  Vector3d distributed = Vector3d::Zero();
  double inertia = 0.0;     // max(I1, I2)
};

RodStiffness rodStiffness(const geometry::MechanicsSpec& spec, const geometry::Rod& src) {
  double nu = spec.poissonRatio;
  std::optional<double> shear = spec.shearFactor, torsion;
  for (const auto& over : spec.rods)
    if (over.rod == src.name()) {
      if (over.poissonRatio) nu = *over.poissonRatio;
      if (over.shearFactor) shear = *over.shearFactor;
      torsion = over.torsionConstant;
    }
  SectionProperties props = sectionProperties(src.section(), nu);
  if (shear) props.shearFactor = *shear;
  if (torsion) props.torsionConstant = *torsion;
  const double G = 1.0 / (2.0 * (1.0 + nu));  // per unit E
  RodStiffness k;
  k.shearExtension = Vector3d(props.shearFactor * G * props.area, props.shearFactor * G * props.area, props.area);
  k.bendingTorsion = Vector3d(props.inertia1, props.inertia2, G * props.torsionConstant);
  k.inertia = std::max(props.inertia1, props.inertia2);
  for (const auto& d : spec.distributedLoads)
    if (d.rod == src.name()) k.distributed += d.force;
  return k;
}

// Reference positions and quaternions (a row of 7 per control point) interpolating the design's
// centerline and frames at the collocation points, so the unit-norm conditions hold exactly in the
// reference state. Fills rod.basis.
Eigen::MatrixXd interpolateReference(const DiscreteStructure& s, DiscreteRod& rod, const geometry::Rod& src) {
  const geometry::NurbsCurve& c0 = src.centerline();
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
  if (lu.info() != Eigen::Success) s.fail(rod.path + ".centerline", "the collocation matrix is singular");
  return lu.solve(samples);
}

}  // namespace

void DiscreteStructure::buildRod(const geometry::RodStructure& structure, std::size_t index,
                                 const Discretization& discretization) {
  const geometry::Rod& src = structure.rods[index];
  DiscreteRod rod;
  rod.name = src.name();
  rod.path = "rods[" + std::to_string(index) + "]";
  rod.source = &src;
  const geometry::NurbsCurve& c0 = src.centerline();
  const bool rebuild = discretization.degree > 0 && (discretization.degree != c0.degree() || discretization.spans > 0);
  const int p = rebuild ? discretization.degree : c0.degree();
  checkCenterline(*this, c0, p, rod.path);
  rod.curve = solverCurve(c0, discretization, rebuild, p);
  rod.degree = p;
  rod.count = static_cast<int>(rod.curve.points().size());
  if (rod.count < 3) fail(rod.path + ".centerline.points", "needs at least 3 control points");
  rod.length = src.length();
  rod.tau = grevilleAbscissae(rod.curve);
  const geometry::BSplineField& e = src.modulus();
  checkModulusKinks(*this, e, rod.tau, rod.path);
  const RodStiffness stiffness = rodStiffness(structure.mechanics, src);

  const Eigen::MatrixXd interpolated = interpolateReference(*this, rod, src);
  if (rebuild) {
    std::vector<Vec3> points(rod.count);
    for (int i = 0; i < rod.count; ++i) points[i] = interpolated.block<1, 3>(i, 0).transpose();
    rod.curve = geometry::NurbsCurve(p, rod.curve.knots(), std::move(points));
  }
  rod.offset = unknowns;
  unknowns += 7 * static_cast<std::size_t>(rod.count);
  reference.conservativeResize(static_cast<Eigen::Index>(unknowns));
  for (int i = 0; i < rod.count; ++i) {
    reference.segment<3>(rod.offset + 7 * i) = rod.curve.points()[i];
    reference.segment<4>(rod.offset + 7 * i + 3) = interpolated.block<1, 4>(i, 3).transpose();
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
    c.shearExtension = stiffness.shearExtension;
    c.bendingTorsion = stiffness.bendingTorsion;
    c.distributedForce = stiffness.distributed;
    eMax = std::max(eMax, c.E);
  }
  // Residual rows in units of the rod's bending: E I / L^2 for forces, E I / L for moments. A scale
  // by E A would hide the loads that bend slender rods (E A L^2 / E I = (L / r)^2 is 1e6 and more).
  const double bending = eMax * stiffness.inertia;
  rod.forceScale = bending / (rod.length * rod.length);
  rod.momentScale = bending / rod.length;
  rods.push_back(std::move(rod));
}

}  // namespace rodfab::mechanics::detail
