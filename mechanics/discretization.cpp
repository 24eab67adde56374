// Each rod on its solver basis (solver_basis.cpp chooses it): the reference state interpolating
// the design's centerline and frames at the collocation points, and the pointwise constants.
#include "common/json_input.hpp"
#include "mechanics/discrete_structure.hpp"
#include "mechanics/section_properties.hpp"
#include "mechanics/solver_basis.hpp"

#include <Eigen/Geometry>
#include <Eigen/SparseLU>
#include <boost/math/tools/minima.hpp>

#include <algorithm>
#include <cstdint>
#include <limits>
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

std::optional<Eigen::MatrixXd> interpolateAtCollocationPoints(const DiscreteRod& rod, const Eigen::MatrixXd& samples) {
  std::vector<Eigen::Triplet<double>> entries;
  for (int j = 0; j < rod.count; ++j)
    for (int k = 0; k < rod.basis[j].count; ++k) entries.emplace_back(j, rod.basis[j].first + k, rod.basis[j].value[k]);
  Eigen::SparseMatrix<double> collocation(rod.count, rod.count);
  collocation.setFromTriplets(entries.begin(), entries.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(collocation);
  if (lu.info() != Eigen::Success) return std::nullopt;
  return Eigen::MatrixXd(lu.solve(samples));
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

// Section stiffness per unit E and the distributed load of one rod, with the design's overrides.
struct RodStiffness {
  Vector3d shearExtension;  // (k G A, k G A, A)
  Vector3d bendingTorsion;  // (I1, I2, G J)
  Vector3d distributed = Vector3d::Zero();
  double inertia = 0.0;     // max(I1, I2)
};

RodStiffness rodStiffness(const MechanicsSpec& spec, const geometry::Rod& src) {
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
  rod.siteBelow.clear();
  for (double u : rod.sites) rod.siteBelow.push_back(rationalBasisBelow(rod.curve, u));
  Eigen::MatrixXd samples(rod.count, 7);
  Vector4d previous = Vector4d::Zero();
  for (int j = 0; j < rod.count; ++j) {
    Vector4d q = unitQuaternion(src.frame().at(c0, rod.tau[j]));
    if (j > 0 && q.dot(previous) < 0) q = -q;
    samples.block<1, 3>(j, 0) = c0.point(rod.tau[j]).transpose();
    samples.block<1, 4>(j, 3) = q.transpose();
    previous = q;
  }
  const std::optional<Eigen::MatrixXd> values = interpolateAtCollocationPoints(rod, samples);
  if (!values) s.fail(rod.path + ".centerline", "the collocation matrix is singular");
  return *values;
}

// The reference strains, E and dE/du, the section and the distributed load at parameter u with
// basis b (a collocation point, or an interior site from below).
PointConstants pointConstants(const DiscreteStructure& s, const DiscreteRod& rod, const Basis& b, double u,
                              const geometry::BSplineField& e, const RodStiffness& stiffness) {
  const LocalState state = localState(rod, b, s.reference);
  const StrainMeasures<double> sm = strainMeasures<double>(state.dr, state.ddr, state.q, state.dq, state.ddq);
  PointConstants c;
  c.J0 = state.dr.norm();
  if (!(c.J0 > 0)) s.fail(rod.path + ".centerline", "the centerline's derivative vanishes at u = " + format(u));
  c.dJ0 = state.dr.dot(state.ddr) / c.J0;
  c.gamma0 = sm.gamma, c.dGamma0 = sm.dGamma, c.curvature0 = sm.curvature, c.dCurvature0 = sm.dCurvature;
  c.E = e.value(u);
  c.dE = e.isConstant() ? 0.0 : e.derivative(u);
  c.shearExtension = stiffness.shearExtension;
  c.bendingTorsion = stiffness.bendingTorsion;
  c.distributedForce = stiffness.distributed;
  return c;
}

// Per collocation point and interior site (from below) the pointwise constants; then the rod's
// residual scales.
void setPointConstants(const DiscreteStructure& s, DiscreteRod& rod, const geometry::BSplineField& e,
                       const RodStiffness& stiffness) {
  double eMax = 0;
  rod.constants.resize(rod.count);
  for (int j = 0; j < rod.count; ++j) {
    rod.constants[j] = pointConstants(s, rod, rod.basis[j], rod.tau[j], e, stiffness);
    eMax = std::max(eMax, rod.constants[j].E);
  }
  rod.siteBelowConstants.clear();
  for (std::size_t i = 0; i < rod.sites.size(); ++i)
    rod.siteBelowConstants.push_back(pointConstants(s, rod, rod.siteBelow[i], rod.sites[i], e, stiffness));
  // Residual rows in units of the rod's bending: E I / L^2 for forces, E I / L for moments. A scale
  // by E A would hide the loads that bend slender rods (E A L^2 / E I = (L / r)^2 is 1e6 and more).
  const double bending = eMax * stiffness.inertia;
  rod.forceScale = bending / (rod.length * rod.length);
  rod.momentScale = bending / rod.length;
}

// NURBS weights far apart make the curve's parameter run unevenly (weights [1, w, 1] on a quadratic:
// its speed varies 13 times at w = 0.1, 140 times at 0.01, 1,400 times at 0.001), and the solver
// collocates in the parameter: a cantilever of weights [1, 0.001, 1] bent 15 times too little with
// its error estimate a tenth of that (mechanics/README.md, "Uneven parameters").
void refuseUnevenWeights(const DiscreteStructure& s, const geometry::Rod& src, const std::string& path) {
  const std::vector<double>& w = src.centerline().weights();
  if (w.empty()) return;
  const auto [low, high] = std::minmax_element(w.begin(), w.end());
  constexpr double kMaxWeightRatio = 100.0;
  if (*high > kMaxWeightRatio * *low)
    s.fail(path + ".centerline.weights", "weights from " + format(*low) + " to " + format(*high) + " (a ratio over " +
                                             format(kMaxWeightRatio) + ") make the curve's parameter run too unevenly for the "
                                             "solver, which collocates in it; re-fit the centerline with weights closer together");
}

// The parametric speed |dr/du| where it is least along the centerline: a dense sampling per span
// (and at every breakpoint, where repeated control points stop it), its smallest sample then narrowed
// between its neighbours by Brent's method (Boost.Math, as calibration's fit).
std::pair<double, double> slowestParameter(const geometry::NurbsCurve& c, double& fastest) {
  const auto speed = [&](double u) {
    Vec3 d[2];
    c.derivatives(u, 1, d);
    return d[1].norm();
  };
  const std::vector<double>& breaks = c.breakpoints();
  constexpr int kPerSpan = 64;
  std::vector<double> us;
  for (std::size_t b = 0; b + 1 < breaks.size(); ++b)
    for (int i = 0; i < kPerSpan; ++i) us.push_back(breaks[b] + (breaks[b + 1] - breaks[b]) * i / kPerSpan);
  us.push_back(breaks.back());
  std::vector<double> speeds(us.size());
  std::transform(us.begin(), us.end(), speeds.begin(), speed);
  fastest = *std::max_element(speeds.begin(), speeds.end());
  const std::size_t slowest = static_cast<std::size_t>(std::min_element(speeds.begin(), speeds.end()) - speeds.begin());
  std::uintmax_t iterations = 60;
  const auto [u, v] = boost::math::tools::brent_find_minima(speed, us[slowest > 0 ? slowest - 1 : 0], us[std::min(slowest + 1, us.size() - 1)],
                                                            std::numeric_limits<double>::digits / 2, iterations);
  return v < speeds[slowest] ? std::pair{u, v} : std::pair{us[slowest], speeds[slowest]};
}

// A centerline whose parameter nearly stops (repeated control points, a cusp) is collocated there as
// unevenly as under weights far apart (refuseUnevenWeights), and its derivative may vanish between the
// collocation points: a straight rod with a repeated middle control point bent 10 % too little as a
// cantilever, nothing said. Speeds more than 1,000 times apart (weights of 0.001 did 1,400) are refused.
void refuseStoppingParameter(const DiscreteStructure& s, const geometry::Rod& src, const std::string& path) {
  double fastest = 0;
  const auto [u, slowest] = slowestParameter(src.centerline(), fastest);
  if (slowest > 1e-3 * fastest) return;
  s.fail(path + ".centerline", slowest <= 1e-12 * fastest
                                   ? "the centerline's derivative vanishes at u = " + format(u) + " (control points repeated there?)"
                                   : "its parameter runs " + format(fastest / slowest) + " times slower at u = " + format(u) +
                                         " than where it is fastest (more than 1000: too unevenly for the solver, which "
                                         "collocates in it); re-fit the centerline with its control points more evenly spaced");
}

// Stiffness overrides far outside what any section can have: a torsion constant of 1e-300 mm^4 was
// reported as "a mechanism (add supports)", a shear factor of 1e-300 as Newton failing. A solid
// section's torsion constant lies below its polar moment I1 + I2, and shear factors near 5/6.
void refuseAbsurdStiffness(const DiscreteStructure& s, const MechanicsSpec& spec, const geometry::Rod& src) {
  const SectionProperties own = sectionProperties(src.section(), spec.poissonRatio);
  const auto where = [&](const char* field) { return common::memberPath(common::memberPath("mechanics.rods", src.name()), field); };
  for (const RodMechanics& over : spec.rods) {
    if (over.rod != src.name()) continue;
    const double polar = own.inertia1 + own.inertia2;
    if (over.torsionConstant && !(*over.torsionConstant >= 1e-6 * own.torsionConstant && *over.torsionConstant <= 10 * polar))
      s.fail(where("torsion_constant"), format(*over.torsionConstant) + " mm^4 is outside 1e-6 of the section's own (" +
                                            format(own.torsionConstant) + " mm^4) to 10 times its polar moment (" + format(polar) +
                                            " mm^4): no section of this size has it (units?)");
    if (over.shearFactor && !(*over.shearFactor >= 1e-3 && *over.shearFactor <= 10))
      s.fail(where("shear_factor"), format(*over.shearFactor) + " is outside 0.001 to 10 (a solid section's is near 5/6)");
  }
  if (spec.shearFactor && !(*spec.shearFactor >= 1e-3 && *spec.shearFactor <= 10))
    s.fail("mechanics.shear_factor", format(*spec.shearFactor) + " is outside 0.001 to 10 (a solid section's is near 5/6)");
}

}  // namespace

void DiscreteStructure::buildRod(const Design& structure, std::size_t index,
                                 const Discretization& discretization) {
  const geometry::Rod& src = structure.rods[index];
  DiscreteRod rod;
  rod.name = src.name();
  rod.path = "rods[" + std::to_string(index) + "]";
  rod.source = &src;
  refuseUnevenWeights(*this, src, rod.path);
  refuseStoppingParameter(*this, src, rod.path);
  refuseAbsurdStiffness(*this, structure.mechanics, src);
  RodBasisChoice choice = chooseBasis(*this, src, index, discretization, rod.path);
  // Spans the user chose are kept (a kink on a collocation point is then refused); automatic ones
  // grow by one until no kink of E(s) is a collocation point.
  const bool chosen = index >= discretization.perRod.size() && (choice.rebuild ? discretization.spans > 0 : discretization.refine >= 0);
  rod.sites = interiorSites[index];
  for (int attempt = 0;; ++attempt) {
    rod.curve = solverCurve(src, choice, rod.sites);
    rod.tau = grevilleAbscissae(rod.curve);
    rod.sitePoints = sitePoints(rod.curve, rod.sites, rod.tau);
    const std::optional<double> kink = kinkAtCollocationPoint(src.modulus(), rod.tau, rod.sitePoints);
    if (!kink) break;
    if (chosen || attempt == 16)
      fail(rod.path + ".modulus", "E(s) has a kink at u = " + format(*kink) + ", which is a collocation point of this "
           "discretization, where the solver needs E'(s); choose other " + (choice.rebuild ? "--spans" : "--refine") +
           " (or leave them automatic), or raise the field's degree");
    ++choice.spans;
  }
  rod.degree = choice.degree;
  rod.spans = choice.spans;
  rod.rebuilt = choice.rebuild;
  rod.count = static_cast<int>(rod.curve.points().size());
  if (rod.count < 3) fail(rod.path + ".centerline.points", "needs at least 3 control points");
  // About 5 kB per unknown (Jacobian, its factors, the assembly's maps): refuse before allocating.
  if (unknowns + 7 * static_cast<std::size_t>(rod.count) > kMaxUnknowns)
    fail(rod.path, "the discretization passes " + std::to_string(kMaxUnknowns) + " unknowns here (about " +
                       std::to_string(kMaxUnknowns / 200000) + " GB); use fewer --spans or a coarser --accuracy");
  rod.length = src.length();

  const Eigen::MatrixXd interpolated = interpolateReference(*this, rod, src);
  if (choice.rebuild) {
    std::vector<Vec3> points(rod.count);
    for (int i = 0; i < rod.count; ++i) points[i] = interpolated.block<1, 3>(i, 0).transpose();
    rod.curve = geometry::NurbsCurve(rod.degree, rod.curve.knots(), std::move(points));
  }
  rod.offset = unknowns;
  unknowns += 7 * static_cast<std::size_t>(rod.count);
  reference.conservativeResize(static_cast<Eigen::Index>(unknowns));
  for (int i = 0; i < rod.count; ++i) {
    reference.segment<3>(rod.offset + 7 * i) = rod.curve.points()[i];
    reference.segment<4>(rod.offset + 7 * i + 3) = interpolated.block<1, 4>(i, 3).transpose();
  }

  setPointConstants(*this, rod, src.modulus(), rodStiffness(structure.mechanics, src));
  rods.push_back(std::move(rod));
}

}  // namespace rodfab::mechanics::detail
