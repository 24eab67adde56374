// Design sensitivities of the discrete system: its derivative with respect to the modulus control
// values, setting a new modulus field on a fixed discretization, and the state as a linear
// function of the unknowns for shape objectives (optimize/).
#include "mechanics/discrete_structure.hpp"

#include <algorithm>
#include <cmath>

namespace rodfab::mechanics {

using namespace detail;

namespace {

// Values and u-derivatives of the field's non-zero basis functions at u (clamped to its domain).
struct FieldBasis {
  int first = 0, count = 0;
  geometry::BasisDerivatives ders;
};

FieldBasis fieldBasis(const geometry::BSplineField& e, double u) {
  FieldBasis b;
  u = std::clamp(u, e.domainBegin(), e.domainEnd());
  const int n = static_cast<int>(e.values().size());
  const int span = geometry::findKnotSpan(e.knots(), e.degree(), n, u);
  geometry::basisFunctionDerivatives(e.knots(), e.degree(), span, u, 1, b.ders);
  b.first = span - e.degree();
  b.count = e.degree() + 1;
  // A constant field has no slope for the solver (setPointConstants): its dE is 0 whatever the values.
  if (e.isConstant()) std::fill(b.ders[1].begin(), b.ders[1].end(), 0.0);
  return b;
}

// The rows of one work item and the derivatives of their residual with respect to the E and dE/du
// constants of one collocation point, found from the residual's linearity in them.
struct PointDerivative {
  std::vector<std::size_t> rows;
  Eigen::VectorXd byE, byDE;
};

class Differentiator {
public:
  Differentiator(const DiscreteStructure& s, const Eigen::VectorXd& x, double load)
      : s_(s), x_(x), load_(load), residual_(Eigen::VectorXd::Zero(x.size())) {
    scratch_.source = s.source;
    scratch_.rods = s.rods;
  }

  // Rows of the interior item (rod, j): they depend on that point's constants only.
  PointDerivative interior(int rod, int j) {
    PointDerivative d;
    for (int r = 0; r < 7; ++r) d.rows.push_back(s_.rods[rod].row(j) + r);
    differentiate(rod, j, d, [&] { scratch_.interiorBlock(scratch_.rods[rod], j, x_, load_, residual_, nullptr); });
    return d;
  }

  // Rows of a node with respect to the constants at its site `i`. An interior site's two sides
  // carry the same E and dE/du (the field's value and derivative there, as setPointConstants sets
  // them). They enter the balance rows only, through that site's own force and moment, so the node
  // made of its first site and site i gives the same derivative (to rounding) at a cost that does
  // not grow with the node's other sites: O(N) for a joint of N rod ends, not O(N^2).
  PointDerivative node(const Node& node, std::size_t i) {
    const Node pair = node.pairWith(i);
    const Site& site = node.ends[i];
    PointDerivative d;
    for (const Site& e : pair.ends)
      for (int r = 0; r < 7; ++r) d.rows.push_back(s_.siteRow(e) + r);
    PointConstants* below =
        site.end == Site::kInterior ? &scratch_.rods[site.rod].siteBelowConstants[site.index] : nullptr;
    differentiate(site.rod, s_.rods[site.rod].point(site), d,
                  [&] { scratch_.nodeBlock(pair, x_, load_, residual_, nullptr); }, below);
    return d;
  }

private:
  template <class Evaluate>
  void differentiate(int rod, int j, PointDerivative& d, const Evaluate& evaluate, PointConstants* below = nullptr) {
    PointConstants& c = scratch_.rods[rod].constants[j];
    const PointConstants kept = c;
    const PointConstants keptBelow = below ? *below : kept;
    const auto set = [&](double e, double de) {
      c.E = e, c.dE = de;
      if (below) below->E = e, below->dE = de;
    };
    const auto rowsNow = [&] {
      evaluate();
      Eigen::VectorXd v(static_cast<Eigen::Index>(d.rows.size()));
      for (std::size_t i = 0; i < d.rows.size(); ++i) v[static_cast<Eigen::Index>(i)] = residual_[static_cast<Eigen::Index>(d.rows[i])];
      return v;
    };
    set(0, 0);
    const Eigen::VectorXd base = rowsNow();
    set(1, 0);
    d.byE = rowsNow() - base;
    set(0, 1);
    d.byDE = rowsNow() - base;
    c = kept;
    if (below) *below = keptBelow;
  }

  const DiscreteStructure& s_;
  const Eigen::VectorXd& x_;
  double load_;
  DiscreteStructure scratch_;
  Eigen::VectorXd residual_;
};

}  // namespace

const geometry::BSplineField& StaticProblem::modulus(std::size_t rod) const {
  if (rod < moduli_.size() && moduli_[rod]) return *moduli_[rod];
  return structure_->rods.at(rod).source->modulus();
}

std::size_t StaticProblem::modulusVariableOffset(std::size_t rod) const {
  if (rod > structure_->rods.size()) throw std::out_of_range("StaticProblem::modulusVariableOffset: no such rod");
  std::size_t offset = 0;
  for (std::size_t r = 0; r < rod; ++r) offset += modulus(r).values().size();
  return offset;
}

std::size_t StaticProblem::modulusVariableCount() const { return modulusVariableOffset(structure_->rods.size()); }

void StaticProblem::setModulus(std::size_t rod, const geometry::BSplineField& field) {
  DiscreteRod& r = structure_->rods.at(rod);
  const geometry::BSplineField& old = modulus(rod);
  if (field.degree() != old.degree() || field.knots() != old.knots())
    throw std::invalid_argument("StaticProblem::setModulus: rod " + r.name + ": the new field needs the old one's degree and knots");
  double oldMax = 0, newMax = 0;
  std::vector<PointConstants> constants = r.constants;
  for (int j = 0; j < r.count; ++j) {
    oldMax = std::max(oldMax, constants[j].E);
    constants[j].E = field.value(r.tau[j]);
    constants[j].dE = old.isConstant() ? 0.0 : field.derivative(r.tau[j]);
    if (!std::isfinite(constants[j].E) || !(constants[j].E > 0) || !std::isfinite(constants[j].dE))
      throw std::invalid_argument("StaticProblem::setModulus: rod " + r.name + ": E must be finite and positive, got " +
                                  format(constants[j].E) + " at u = " + format(r.tau[j]));
    newMax = std::max(newMax, constants[j].E);
  }
  // An interior site's lower side (T-joints, interior loads and supports) has the same E and dE/du.
  for (std::size_t i = 0; i < r.sites.size(); ++i) {
    r.siteBelowConstants[i].E = field.value(r.sites[i]);
    r.siteBelowConstants[i].dE = old.isConstant() ? 0.0 : field.derivative(r.sites[i]);
  }
  r.constants = std::move(constants);
  r.forceScale *= newMax / oldMax;
  r.momentScale *= newMax / oldMax;
  if (moduli_.size() < structure_->rods.size()) moduli_.resize(structure_->rods.size());
  moduli_[rod] = field;
}

Eigen::SparseMatrix<double> StaticProblem::modulusJacobian(const Eigen::VectorXd& x, double load) const {
  const DiscreteStructure& s = *structure_;
  if (static_cast<std::size_t>(x.size()) != s.unknowns) throw std::invalid_argument("StaticProblem::modulusJacobian: wrong state size");
  std::vector<std::size_t> offsets;
  for (std::size_t r = 0; r <= s.rods.size(); ++r) offsets.push_back(modulusVariableOffset(r));
  Differentiator differentiator(s, x, load);
  std::vector<Eigen::Triplet<double>> entries;
  // dR/dE_k = sum over points p of N_k(tau_p) dR/dE_p + N_k'(tau_p) dR/d(dE)_p.
  const auto add = [&](int rod, int j, const PointDerivative& d) {
    const FieldBasis b = fieldBasis(modulus(rod), s.rods[rod].tau[j]);
    for (int k = 0; k < b.count; ++k)
      for (std::size_t i = 0; i < d.rows.size(); ++i) {
        const double v = b.ders[0][k] * d.byE[static_cast<Eigen::Index>(i)] + b.ders[1][k] * d.byDE[static_cast<Eigen::Index>(i)];
        if (v != 0.0) entries.emplace_back(static_cast<int>(d.rows[i]), static_cast<int>(offsets[rod] + b.first + k), v);
      }
  };
  for (const WorkItem& item : s.items) {
    if (item.rod >= 0) {
      add(item.rod, item.point, differentiator.interior(item.rod, item.point));
      continue;
    }
    const Node& node = s.nodes[item.point];
    for (std::size_t i = 0; i < node.ends.size(); ++i)
      add(node.ends[i].rod, s.rods[node.ends[i].rod].point(node.ends[i]), differentiator.node(node, i));
  }
  Eigen::SparseMatrix<double> m(static_cast<Eigen::Index>(s.unknowns), static_cast<Eigen::Index>(offsets.back()));
  m.setFromTriplets(entries.begin(), entries.end());
  return m;
}

const std::vector<double>& StaticProblem::collocationPoints(std::size_t rod) const { return structure_->rods.at(rod).tau; }
const std::vector<double>& StaticProblem::interiorSites(std::size_t rod) const { return structure_->rods.at(rod).sites; }

StaticProblem::StateJet StaticProblem::stateJet(const Eigen::VectorXd& x, std::size_t rod, double u) const {
  const DiscreteRod& r = structure_->rods.at(rod);
  if (static_cast<std::size_t>(x.size()) != structure_->unknowns) throw std::invalid_argument("StaticProblem::stateJet: wrong state size");
  const Basis b = rationalBasis(r.curve, std::clamp(u, r.curve.domainBegin(), r.curve.domainEnd()));
  const LocalState s = localState(r, b, x);
  StateJet jet{s.r, s.dr, s.q, s.dq, {}, {}, {}};
  for (int k = 0; k < b.count; ++k) {
    jet.first.push_back(r.offset + 7 * static_cast<std::size_t>(b.first + k));
    jet.value.push_back(b.value[k]);
    jet.d1.push_back(b.d1[k]);
  }
  return jet;
}

}  // namespace rodfab::mechanics
