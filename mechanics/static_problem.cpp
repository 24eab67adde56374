// StaticProblem: builds the discrete structure and evaluates its residual and Jacobian.
#include "mechanics/discrete_structure.hpp"

#include "common/interrupt.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>

namespace rodfab::mechanics {

using namespace detail;
using geometry::Vec3;
using Eigen::Vector4d;

namespace {

bool samePattern(const Eigen::SparseMatrix<double>& a, const Eigen::SparseMatrix<double>& b) {
  return a.isCompressed() && a.rows() == b.rows() && a.cols() == b.cols() && a.nonZeros() == b.nonZeros() &&
         std::equal(a.outerIndexPtr(), a.outerIndexPtr() + a.cols() + 1, b.outerIndexPtr()) &&
         std::equal(a.innerIndexPtr(), a.innerIndexPtr() + a.nonZeros(), b.innerIndexPtr());
}

}  // namespace

StaticProblem::StaticProblem(const Design& structure, const Discretization& discretization)
    : structure_(std::make_unique<DiscreteStructure>()) {
  DiscreteStructure& m = *structure_;
  m.source = structure.source;
  if (discretization.refine < -1 || discretization.refine >= kMaxSpansPerRod || discretization.spans < 0 ||
      discretization.spans > kMaxSpansPerRod || discretization.degree < 0 || discretization.degree > geometry::kMaxDegree ||
      !(discretization.tolerance > 0) || discretization.tolerance > 1)
    throw std::invalid_argument("StaticProblem: degree 0.." + std::to_string(geometry::kMaxDegree) + ", refine -1.." +
                                std::to_string(kMaxSpansPerRod - 1) + ", spans 0.." + std::to_string(kMaxSpansPerRod) +
                                " and tolerance in (0, 1] expected");
  if (!structure.mechanics.present)
    m.fail("mechanics", "the design has no \"mechanics\" block: give at least its supports (and loads) to simulate it");
  m.findInteriorSites(structure);
  for (std::size_t i = 0; i < structure.rods.size(); ++i) {
    common::throwIfInterrupted();  // thousands of rods, each interpolated, take seconds
    m.buildRod(structure, i, discretization);
  }
  m.size = std::max(1e-12, structure.bounds().diagonal().norm());
  m.buildNodes(structure);
  m.keepSpec(structure);
  m.discretization = discretization;
  m.discretization.perRod.clear();
  for (const DiscreteRod& rod : m.rods) m.discretization.perRod.push_back(rod.spans);
  for (std::size_t r = 0; r < m.rods.size(); ++r)
    for (int j = 1; j + 1 < m.rods[r].count; ++j)
      if (!m.rods[r].isSitePoint(j)) m.items.push_back({static_cast<int>(r), j});
  for (std::size_t n = 0; n < m.nodes.size(); ++n) m.items.push_back({-1, static_cast<int>(n)});
  m.buildLayouts();
}

std::pair<std::string, double> StaticProblem::mostSlenderRod() const {
  std::pair<std::string, double> most{"", 0.0};
  for (std::size_t r = 0; r < structure_->rods.size(); ++r) {
    const DiscreteRod& rod = structure_->rods[r];
    const geometry::Section& section = rod.source->section();
    const double ratio = rod.length / std::min(section.width, section.height);
    if (ratio > most.second) most = {rod.path + " \"" + rod.name + "\"", ratio};
  }
  return most;
}

Design loadCaseStructure(const Design& design, const LoadCase& loadCase) {
  Design out;
  out.source = design.source;
  out.rods = design.rods;
  out.mechanics = design.mechanics;
  out.mechanics.supports = loadCase.supports;
  out.mechanics.loads = loadCase.loads;
  out.mechanics.distributedLoads = loadCase.distributedLoads;
  out.mechanics.loadSteps = loadCase.loadSteps;
  out.mechanics.loadCases.clear();
  return out;
}

void checkMechanics(const Design& design) {
  if (!design.mechanics.present) return;
  const MechanicsSpec& m = design.mechanics;
  // The block's own supports and loads are what simulate solves, load cases or not.
  if (m.loadCases.empty() || !m.supports.empty() || !m.loads.empty() || !m.distributedLoads.empty()) StaticProblem problem(design);
  for (const LoadCase& lc : m.loadCases) {
    const Design structure = loadCaseStructure(design, lc);  // outlives the problem, which points into it
    try {
      StaticProblem problem(structure);
    } catch (const MechanicsError& e) {
      // FILE: load case "NAME" (PATH): JSON.PATH: what
      std::string what = e.what();
      const std::string file = design.source + ": ", which = "load case \"" + lc.name + "\" (" + lc.path + "): ";
      what.insert(what.starts_with(file) ? file.size() : 0, which);
      throw MechanicsError(what);
    }
  }
}

StaticProblem::~StaticProblem() = default;
StaticProblem::StaticProblem(StaticProblem&&) noexcept = default;
StaticProblem& StaticProblem::operator=(StaticProblem&&) noexcept = default;

std::size_t StaticProblem::unknownCount() const { return structure_->unknowns; }
std::size_t StaticProblem::rodCount() const { return structure_->rods.size(); }
std::size_t StaticProblem::jointCount() const { return structure_->joints; }
std::size_t StaticProblem::supportCount() const { return structure_->supports; }
const std::string& StaticProblem::source() const { return structure_->source; }
const Discretization& StaticProblem::discretization() const { return structure_->discretization; }

int StaticProblem::convergenceOrder() const {
  int order = geometry::kMaxDegree;
  for (const DiscreteRod& rod : structure_->rods) order = std::min(order, rod.degree % 2 == 0 ? rod.degree : rod.degree - 1);
  return order;
}
std::optional<UnderResolvedRod> StaticProblem::leastResolvedRod() const {
  std::optional<UnderResolvedRod> least;
  double shortest = 1.0;  // spans over those needed
  const double relative = std::max(1e-2, structure_->discretization.tolerance);
  for (const DiscreteRod& rod : structure_->rods) {
    const int spans = static_cast<int>(rod.curve.breakpoints().size()) - 1;
    const double needed = aPrioriSpans(*rod.source, rod.degree, relative);
    if (spans < needed && spans / needed < shortest) {
      shortest = spans / needed;
      least = UnderResolvedRod{rod.path + " \"" + rod.name + "\"", rod.degree, spans, needed, relative};
    }
  }
  return least;
}

std::optional<std::string> StaticProblem::stabilityBlindSpot() const {
  for (const Node& node : structure_->nodes)
    if (node.hasFollower)
      return std::string("follower loads are not conservative, and det J does not decide stability under them");
  return std::nullopt;
}

const Eigen::VectorXd& StaticProblem::referenceState() const { return structure_->reference; }

void StaticProblem::evaluate(const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                             Eigen::SparseMatrix<double>* jacobian) const {
  const DiscreteStructure& m = *structure_;
  if (static_cast<std::size_t>(x.size()) != m.unknowns) throw std::invalid_argument("StaticProblem::evaluate: wrong state size");
  residual.resize(x.size());
  if (jacobian && !samePattern(*jacobian, m.pattern)) *jacobian = m.pattern;
  double* values = jacobian ? jacobian->valuePtr() : nullptr;
  tbb::enumerable_thread_specific<Eigen::MatrixXd> scratch;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m.items.size(), 64), [&](const tbb::blocked_range<std::size_t>& range) {
    Eigen::MatrixXd* block = values ? &scratch.local() : nullptr;
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const WorkItem& item = m.items[i];
      const ItemLayout& layout = m.layouts[i];
      if (item.rod >= 0) m.interiorBlock(m.rods[item.rod], item.point, x, load, residual, block);
      else m.nodeBlock(m.nodes[item.point], x, load, residual, block, &layout);
      if (!block) continue;
      // Each row belongs to one item, so items write disjoint entries; an entry an item's block
      // holds twice (a closed rod) is summed.
      const int* slot = m.slots.data() + layout.firstSlot;
      const std::size_t count = 7 * layout.width;
      for (std::size_t k = 0; k < count; ++k)
        if (slot[k] >= 0) values[slot[k]] = 0.0;
      for (std::size_t k = 0; k < count; ++k)
        if (slot[k] >= 0) values[slot[k]] += block->data()[k];
    }
  });
}

namespace {

// The local state of rod `rod` at u (clamped to the domain) in x, after checking both.
LocalState stateAt(const DiscreteStructure& m, const Eigen::VectorXd& x, std::size_t rod, double u) {
  const DiscreteRod& r = m.rods.at(rod);
  if (static_cast<std::size_t>(x.size()) != m.unknowns) throw std::invalid_argument("StaticProblem: a state of the wrong size");
  return localState(r, rationalBasis(r.curve, std::clamp(u, r.curve.domainBegin(), r.curve.domainEnd())), x);
}

}  // namespace

Eigen::Vector3d StaticProblem::position(const Eigen::VectorXd& x, std::size_t rod, double u) const {
  return stateAt(*structure_, x, rod, u).r;
}

Eigen::Matrix3d StaticProblem::rotation(const Eigen::VectorXd& x, std::size_t rod, double u) const {
  const Vector4d q = stateAt(*structure_, x, rod, u).q;
  return rotationNumerator<double>(q) / q.squaredNorm();
}

Eigen::VectorXd StaticProblem::transferredState(const StaticProblem& from, const Eigen::VectorXd& x) const {
  const DiscreteStructure& m = *structure_;
  const DiscreteStructure& f = *from.structure_;
  if (f.rods.size() != m.rods.size() || static_cast<std::size_t>(x.size()) != f.unknowns)
    throw std::invalid_argument("StaticProblem::transferredState: a state of another structure");
  Eigen::VectorXd out(static_cast<Eigen::Index>(m.unknowns));
  for (std::size_t r = 0; r < m.rods.size(); ++r) {
    const DiscreteRod& rod = m.rods[r];
    const DiscreteRod& source = f.rods[r];
    Eigen::MatrixXd samples(rod.count, 7);
    for (int j = 0; j < rod.count; ++j) {
      const LocalState s = localState(source, rationalBasis(source.curve, rod.tau[j]), x);
      samples.block<1, 3>(j, 0) = s.r.transpose();
      samples.block<1, 4>(j, 3) = s.q.transpose();
    }
    const Eigen::MatrixXd values = *interpolateAtCollocationPoints(rod, samples);  // regular: the reference used it
    for (int i = 0; i < rod.count; ++i) out.segment<7>(rod.offset + 7 * i) = values.row(i).transpose();
  }
  return out;
}

double StaticProblem::stepNorm(const Eigen::VectorXd& dx) const {
  if (static_cast<std::size_t>(dx.size()) != structure_->unknowns) throw std::invalid_argument("StaticProblem::stepNorm: wrong size");
  double norm = 0;
  for (Eigen::Index i = 0; i < dx.size(); i += 7) {
    norm = std::max(norm, dx.segment<3>(i).cwiseAbs().maxCoeff() / structure_->size);
    norm = std::max(norm, dx.segment<4>(i + 3).cwiseAbs().maxCoeff());
  }
  return norm;
}

Design StaticProblem::deformedStructure(const Eigen::VectorXd& x) const {
  const DiscreteStructure& m = *structure_;
  if (static_cast<std::size_t>(x.size()) != m.unknowns) throw std::invalid_argument("StaticProblem::deformedStructure: wrong state size");
  Design out;
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
  out.mechanics = m.spec;
  return out;
}

}  // namespace rodfab::mechanics
