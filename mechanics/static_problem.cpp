// StaticProblem: builds the discrete structure and evaluates its residual and Jacobian.
#include "mechanics/discrete_structure.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>

namespace rodfab::mechanics {

using namespace detail;
using geometry::Vec3;
using Eigen::Vector4d;

StaticProblem::StaticProblem(const geometry::RodStructure& structure, const Discretization& discretization)
    : structure_(std::make_unique<DiscreteStructure>()) {
  DiscreteStructure& m = *structure_;
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

std::size_t StaticProblem::unknownCount() const { return structure_->unknowns; }
std::size_t StaticProblem::rodCount() const { return structure_->rods.size(); }
std::size_t StaticProblem::jointCount() const { return structure_->joints; }
std::size_t StaticProblem::supportCount() const { return structure_->supports; }
const std::string& StaticProblem::source() const { return structure_->source; }
const Eigen::VectorXd& StaticProblem::referenceState() const { return structure_->reference; }

void StaticProblem::evaluate(const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                             Eigen::SparseMatrix<double>* jacobian) const {
  const DiscreteStructure& m = *structure_;
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
  const DiscreteRod& r = structure_->rods.at(rod);
  return localState(r, rationalBasis(r.curve, u), x).r;
}

Eigen::Matrix3d StaticProblem::rotation(const Eigen::VectorXd& x, std::size_t rod, double u) const {
  const DiscreteRod& r = structure_->rods.at(rod);
  const Vector4d q = localState(r, rationalBasis(r.curve, u), x).q;
  return rotationNumerator<double>(q) / q.squaredNorm();
}

double StaticProblem::stepNorm(const Eigen::VectorXd& dx) const {
  double norm = 0;
  for (Eigen::Index i = 0; i < dx.size(); i += 7) {
    norm = std::max(norm, dx.segment<3>(i).cwiseAbs().maxCoeff() / structure_->size);
    norm = std::max(norm, dx.segment<4>(i + 3).cwiseAbs().maxCoeff());
  }
  return norm;
}

geometry::RodStructure StaticProblem::deformedStructure(const Eigen::VectorXd& x) const {
  const DiscreteStructure& m = *structure_;
  geometry::RodStructure out;
  out.source = m.source;
  for (const DiscreteRod& rod : m.rods) {
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
