// Targets and the shape objective (see optimize/optimize.hpp for the formula).
#include "optimize/objective.hpp"
#include "optimize/optimize.hpp"

#include <Eigen/Geometry>
#include <unsupported/Eigen/AutoDiff>

#include <algorithm>
#include <map>

namespace rodfab::optimize::detail {

namespace {

using geometry::Vec3;

// The rotation from frame a to frame b as an axis times its angle, in a's axes.
Eigen::Vector3d turn(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const Eigen::AngleAxisd t(a.transpose() * b);
  return t.axis() * t.angle();
}

// Material curvature per arc length, axial(R^T dR/ds), of the frame field `frameAt` along a curve
// whose speed at u is `speed`: central difference of the rotation (second order), one-sided at
// the domain's ends; `fromAbove`: from above u only, second order (2 t(h) - t(2h) / 2) / h, where
// the curvature jumps at u (an interior site, whose state the solver's basis gives from above).
template <class FrameAt>
Eigen::Vector3d frameCurvature(const FrameAt& frameAt, double u, double begin, double end, double speed, bool fromAbove) {
  const double h = 1e-5 * (end - begin);
  if (fromAbove && u + 2 * h <= end) {
    const Eigen::Matrix3d r0 = frameAt(u);
    return (2.0 * turn(r0, frameAt(u + h)) - 0.5 * turn(r0, frameAt(u + 2 * h))) / (h * speed);
  }
  const double a = std::max(begin, u - h), b = std::min(end, u + h);
  return turn(frameAt(a), frameAt(b)) / ((b - a) * speed);
}

Eigen::Matrix3d frameMatrix(const geometry::Frame& f) {
  Eigen::Matrix3d m;
  m.col(0) = f.d1, m.col(1) = f.d2, m.col(2) = f.d3;
  return m;
}

// The target's position and curvature at the design parameter u of a rod on [begin, end].
struct TargetSampler {
  const mechanics::TargetRod& target;
  geometry::RodFrame frame;  // when the target has no orientation spline

  double map(double u, double begin, double end) const {
    const auto& c = target.centerline;
    return c.domainBegin() + (u - begin) / (end - begin) * (c.domainEnd() - c.domainBegin());
  }
  Eigen::Matrix3d rotation(double v) const {
    if (target.orientation) return target.orientation->rotation(v).toRotationMatrix();
    return frameMatrix(frame.at(target.centerline, v));
  }
  void sample(double v, bool fromAbove, Eigen::Vector3d& position, Eigen::Vector3d& curvature) const {
    const auto& c = target.centerline;
    Vec3 d[2];
    c.derivatives(v, 1, d);
    position = d[0];
    // d/dv of the target's parameter, per arc length of the target.
    curvature = frameCurvature([&](double w) { return rotation(w); }, v, c.domainBegin(), c.domainEnd(), d[1].norm(), fromAbove);
  }
};

}  // namespace

std::vector<RodTarget> sampleTargets(const mechanics::Design& design, const std::vector<mechanics::TargetRod>& targets,
                                     const mechanics::StaticProblem& problem, const std::string& casePath) {
  std::map<std::string, std::size_t> index;
  for (std::size_t r = 0; r < design.rods.size(); ++r) index.emplace(design.rods[r].name(), r);
  std::vector<RodTarget> out;
  std::vector<char> seen(design.rods.size(), 0);
  for (const mechanics::TargetRod& t : targets) {
    const auto found = index.find(t.rod);
    if (found == index.end())
      throw OptimizeError(design.source + ": " + (t.path.empty() ? casePath : t.path) + ": the target names rod \"" + t.rod +
                          "\", which the design does not have");
    if (seen[found->second]++)
      throw OptimizeError(design.source + ": " + (t.path.empty() ? casePath : t.path) + ": rod \"" + t.rod + "\" has two targets");
    const geometry::Rod& rod = design.rods[found->second];
    TargetSampler sampler{t, {}};
    if (!t.orientation) {
      Vec3 d[2];
      t.centerline.derivatives(t.centerline.domainBegin(), 1, d);
      Vec3 normal = t.referenceNormal ? *t.referenceNormal : rod.frame().at(rod.centerline(), rod.centerline().domainBegin()).d1;
      if (normal.cross(d[1]).norm() < 1e-6 * normal.norm() * d[1].norm()) normal = d[1].unitOrthogonal();
      sampler.frame = geometry::RodFrame::rotationMinimizing(t.centerline, normal);
    }
    RodTarget rt;
    rt.rod = found->second;
    rt.length = rod.length();
    const double begin = rod.centerline().domainBegin(), end = rod.centerline().domainEnd();
    const std::vector<double>& sites = problem.interiorSites(rt.rod);
    for (double u : problem.collocationPoints(rt.rod)) {
      Eigen::Vector3d p, k;
      sampler.sample(sampler.map(u, begin, end), std::binary_search(sites.begin(), sites.end(), u), p, k);
      rt.position.push_back(p);
      rt.curvature.push_back(k);
    }
    out.push_back(std::move(rt));
  }
  return out;
}

namespace {

using Dual = Eigen::AutoDiffScalar<Eigen::Matrix<double, 11, 1>>;

// kappa = 2 vec(conj(q) q') / (|q|^2 |r'|) and its derivatives by (r', q, q').
Eigen::Matrix<Dual, 3, 1> curvature(const mechanics::StaticProblem::StateJet& jet) {
  Eigen::Matrix<Dual, 3, 1> dr;
  Eigen::Matrix<Dual, 4, 1> q, dq;
  for (int j = 0; j < 3; ++j) dr[j] = Dual(jet.dr[j], 11, j);
  for (int j = 0; j < 4; ++j) q[j] = Dual(jet.q[j], 11, 3 + j), dq[j] = Dual(jet.dq[j], 11, 7 + j);
  const Eigen::Matrix<Dual, 3, 1> qv = q.tail<3>(), dqv = dq.tail<3>();
  const Eigen::Matrix<Dual, 3, 1> v = q[0] * dqv - dq[0] * qv - qv.cross(dqv);
  return v * (Dual(2.0) / (q.squaredNorm() * dr.norm()));
}

}  // namespace

ShapeTerms shapeObjective(const mechanics::StaticProblem& problem, const std::vector<RodTarget>& targets,
                          const Eigen::VectorXd& x, double positionWeight, double curvatureWeight, bool gradient) {
  ShapeTerms terms;
  if (gradient) terms.gradient = Eigen::VectorXd::Zero(x.size());
  for (const RodTarget& t : targets) {
    const std::vector<double>& tau = problem.collocationPoints(t.rod);
    const double cr = positionWeight / (2.0 * t.length * t.length), ck = curvatureWeight * t.length * t.length / 2.0;
    for (std::size_t i = 0; i < tau.size(); ++i) {
      const auto jet = problem.stateJet(x, t.rod, tau[i]);
      const Eigen::Vector3d dp = jet.r - t.position[i];
      const Eigen::Matrix<Dual, 3, 1> k = curvature(jet);
      Eigen::Vector3d dk;
      for (int j = 0; j < 3; ++j) dk[j] = k[j].value() - t.curvature[i][j];
      terms.position += cr * dp.squaredNorm();
      terms.curvature += ck * dk.squaredNorm();
      if (!gradient) continue;
      // d/d(r', q, q') of ck |dk|^2, then to the control points through the basis.
      Eigen::Matrix<double, 11, 1> local = Eigen::Matrix<double, 11, 1>::Zero();
      for (int j = 0; j < 3; ++j) local += 2.0 * ck * dk[j] * k[j].derivatives();
      for (std::size_t b = 0; b < jet.first.size(); ++b) {
        const auto at = static_cast<Eigen::Index>(jet.first[b]);
        terms.gradient.segment<3>(at) += 2.0 * cr * jet.value[b] * dp + jet.d1[b] * local.head<3>();
        terms.gradient.segment<4>(at + 3) += jet.value[b] * local.segment<4>(3) + jet.d1[b] * local.tail<4>();
      }
    }
  }
  return terms;
}

}  // namespace rodfab::optimize::detail
