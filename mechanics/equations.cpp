// Residual rows and their exact derivatives: interior collocation points (equilibrium and unit
// norm) and nodes (support, balance and joint conditions).
#include "mechanics/discrete_structure.hpp"

#include <unsupported/Eigen/AutoDiff>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace rodfab::mechanics::detail {

using Eigen::Vector3d;
using Eigen::Vector4d;

namespace {

template <int N> using Dual = Eigen::AutoDiffScalar<Eigen::Matrix<double, N, 1>>;
using EndJacobian = Eigen::Matrix<double, 7, 14>;  // one site's 7 rows by an end's (r, r', q, q')

// Columns of the control points `functions` of a basis, 7 per point.
void appendColumns(const DiscreteRod& rod, const Basis& b, const std::vector<int>& functions, std::vector<std::size_t>& cols) {
  for (int k : functions)
    for (int c = 0; c < 7; ++c) cols.push_back(rod.offset + 7 * static_cast<std::size_t>(b.first + k) + c);
}

std::vector<int> allFunctions(const Basis& b) {
  std::vector<int> k(b.count);
  std::iota(k.begin(), k.end(), 0);
  return k;
}

// Chain rule from derivatives with respect to one site side's (r, r', q, q') (14 columns) to its
// control points: function k of the side's basis is control point b.first + k, found in the site's
// column points (7 columns each).
void chainSide(const Basis& b, const EndJacobian& d, const std::vector<int>& points, Eigen::Ref<Eigen::MatrixXd> out) {
  for (int k : endFunctions(b)) {
    const Eigen::Index column =
        7 * (std::lower_bound(points.begin(), points.end(), b.first + k) - points.begin());
    out.middleCols<3>(column) += d.middleCols<3>(0) * b.value[k] + d.middleCols<3>(3) * b.d1[k];
    out.middleCols<4>(column + 3) += d.middleCols<4>(6) * b.value[k] + d.middleCols<4>(10) * b.d1[k];
  }
}

Eigen::Matrix3d crossMatrix(const Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// One node's rows: 7 per site, in the slots of the sites' control points. The first site's slot
// holds the support or balance conditions and its unit norm; every further site's slot ties it to
// the first (position, relative rotation, unit norm). A rod end has one side, an interior site two
// (below and above its C0 knot), each adding its internal force and moment to the balance: the
// jump of n and m across an interior site balances the node's load and the joined rods.
// The derivatives are kept as the node's tiles (Tile): the first site's rows by every site's
// columns, and each further site's rows by its own and the first site's columns. Nothing else is
// coupled, so a joint of N rod ends costs O(N), not the O(N^2) of one dense block.
class NodeEquations {
public:
  NodeEquations(const DiscreteStructure& s, const Node& node, const Eigen::VectorXd& x, bool derivatives)
      : s_(s), node_(node), derivatives_(derivatives) {
    const DiscreteRod& firstRod = s.rodOf(node.ends[0]);
    forceRow_ = 1.0 / firstRod.forceScale, momentRow_ = 1.0 / firstRod.momentScale, positionRow_ = 1.0 / firstRod.length;
    sides_.reserve(2 * node.ends.size());
    for (std::size_t i = 0; i < node.ends.size(); ++i) {
      firstSide_.push_back(static_cast<int>(sides_.size()));
      for (const SiteSide& side : s.sides(node.ends[i])) gatherSide(i, side, x);
    }
    f_.resize(static_cast<Eigen::Index>(7 * node.ends.size()));
    if (!derivatives) return;
    dFirst_.assign(sides_.size(), EndJacobian::Zero());
    dOwn_.assign(node.ends.size(), EndJacobian::Zero());
    dJoint_.assign(node.ends.size(), EndJacobian::Zero());
  }

  void evaluate(double load) {
    if (node_.support) positionRows(load);
    else forceBalanceRows(load);
    if (node_.support == SupportKind::Clamped) rotationRows(load);
    else momentBalanceRows(load);
    f_[6] = site(0).s.q.squaredNorm() - 1.0;
    if (derivatives_) dFirst0().block<1, 4>(6, 6) = 2.0 * site(0).s.q.transpose();
    for (std::size_t i = 1; i < node_.ends.size(); ++i) jointRows(i);
  }

  void scatter(Eigen::VectorXd& residual, Eigen::MatrixXd* block, const ItemLayout* layout) const;

private:
  // Per side: local state, force and moment, and their derivatives with respect to (r, r', q, q').
  struct SideData {
    std::size_t site;
    SiteSide side;
    LocalState s;
    Vector3d n, m;
    Eigen::Matrix<double, 3, 14> dn, dm;
  };

  void gatherSide(std::size_t site, const SiteSide& side, const Eigen::VectorXd& x);
  // A site's first side: its position and rotation (the same on both sides of a C0 knot), and the
  // derivatives of the rows that depend on them only.
  const SideData& site(std::size_t i) const { return sides_[firstSide_[i]]; }
  // The first site's rows by the first site's first side.
  EndJacobian& dFirst0() { return dFirst_[firstSide_[0]]; }
  void positionRows(double load);
  void forceBalanceRows(double load);
  void rotationRows(double load);
  void momentBalanceRows(double load);
  void jointRows(std::size_t i);
  // Adds load R(q) local to rows [row, row + 3) (scaled by `rowScale`), with the derivative with
  // respect to the first site's q: a follower force or moment.
  void addFollower(const Vector3d& local, double load, Eigen::Index row, double rowScale, Vector3d& sum);
  void chainTile(const Tile& tile, Eigen::Ref<Eigen::MatrixXd> out) const;

  const DiscreteStructure& s_;
  const Node& node_;
  bool derivatives_;
  std::vector<SideData> sides_;
  std::vector<int> firstSide_;
  double forceRow_ = 1, momentRow_ = 1, positionRow_ = 1;
  Eigen::VectorXd f_;
  // Derivatives: per side of the first site's rows; per further site of its own rows by its first
  // side, and by the first site's first side.
  std::vector<EndJacobian> dFirst_, dOwn_, dJoint_;
};

void NodeEquations::gatherSide(std::size_t site, const SiteSide& side, const Eigen::VectorXd& x) {
  SideData& d = sides_.emplace_back();
  d.site = site;
  d.side = side;
  d.s = localState(s_.rodOf(node_.ends[site]), *side.basis, x);
  const PointConstants& c = *side.constants;
  if (!derivatives_) {
    const StrainMeasures<double> sm = strainMeasures<double>(d.s.dr, Vector3d::Zero(), d.s.q, d.s.dq, Vector4d::Zero());
    stressResultants(sm, c, d.n, d.m);
    return;
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

void NodeEquations::positionRows(double load) {
  f_.segment<3>(0) = (site(0).s.r - node_.position0 - load * node_.displacement) * positionRow_;
  if (derivatives_) dFirst0().block<3, 3>(0, 0) = Eigen::Matrix3d::Identity() * positionRow_;
}

void NodeEquations::addFollower(const Vector3d& local, double load, Eigen::Index row, double rowScale, Vector3d& sum) {
  if (local.isZero()) return;
  using D = Dual<4>;
  V4<D> q;
  for (int j = 0; j < 4; ++j) q[j] = D(site(0).s.q[j], 4, j);
  const V3<D> f = rotationNumerator<D>(q) * local.cast<D>() / q.squaredNorm() * D(load);
  for (int j = 0; j < 3; ++j) {
    sum[j] += f[j].value();
    if (derivatives_) dFirst0().block<1, 4>(row + j, 6) += rowScale * f[j].derivatives().transpose();
  }
}

void NodeEquations::forceBalanceRows(double load) {
  Vector3d sum = load * node_.force;
  if (node_.hasFollower) addFollower(node_.followerForce, load, 0, forceRow_, sum);
  for (std::size_t k = 0; k < sides_.size(); ++k) {
    sum += sides_[k].side.sign * sides_[k].n;
    if (derivatives_) dFirst_[k].block<3, 14>(0, 0) += sides_[k].side.sign * sides_[k].dn * forceRow_;
  }
  f_.segment<3>(0) = sum * forceRow_;
}

void NodeEquations::rotationRows(double load) {
  // vec(conj(q_target) q) = 0 with q_target the reference end rotation turned by load * rotation.
  const double angle = load * node_.rotation.norm();
  Vector4d turn(1, 0, 0, 0);
  if (angle > 0) turn << std::cos(angle / 2), std::sin(angle / 2) * node_.rotation.normalized();
  const Vector4d target = quaternionProduct<double>(turn, node_.quaternion0);
  f_.segment<3>(3) = conjugateProductVector<double>(target, site(0).s.q);
  if (!derivatives_) return;
  for (int c = 0; c < 4; ++c) dFirst0().block<3, 1>(3, 6 + c) = conjugateProductVector<double>(target, Vector4d::Unit(c));
}

void NodeEquations::momentBalanceRows(double load) {
  Vector3d sum = load * node_.moment;
  if (node_.hasFollower) addFollower(node_.followerMoment, load, 3, momentRow_, sum);
  for (std::size_t k = 0; k < sides_.size(); ++k) {
    const SideData& d = sides_[k];
    const double sign = d.side.sign;
    const Vector3d arm = d.s.r - site(0).s.r;
    sum += sign * (d.m + arm.cross(d.n));
    if (!derivatives_) continue;
    const Eigen::Matrix3d nCross = crossMatrix(d.n);
    dFirst_[k].block<3, 14>(3, 0) += sign * momentRow_ * (d.dm + crossMatrix(arm) * d.dn);
    // arm x n = -n x arm: d(arm) = dr_k - dr_0.
    dFirst_[k].block<3, 3>(3, 0) -= sign * momentRow_ * nCross;
    dFirst0().block<3, 3>(3, 0) += sign * momentRow_ * nCross;
  }
  f_.segment<3>(3) = sum * momentRow_;
}

void NodeEquations::jointRows(std::size_t i) {
  const SideData& e0 = site(0);
  const SideData& d = site(i);
  const Eigen::Index r0 = static_cast<Eigen::Index>(7 * i);
  f_.segment<3>(r0) = (d.s.r - e0.s.r - node_.offsets0[i - 1]) * positionRow_;
  f_[r0 + 6] = d.s.q.squaredNorm() - 1.0;
  // vec(conj(c) conj(q_0) q_i) = vec(conj(q_0 c) q_i) = 0 keeps the relative rotation c.
  using D = Dual<8>;
  V4<D> q0, qi;
  for (int j = 0; j < 4; ++j) q0[j] = D(e0.s.q[j], 8, j), qi[j] = D(d.s.q[j], 8, 4 + j);
  const V3<D> g = conjugateProductVector<D>(quaternionProduct<D>(q0, node_.relative0[i - 1].cast<D>()), qi);
  for (int j = 0; j < 3; ++j) f_[r0 + 3 + j] = g[j].value();
  if (!derivatives_) return;
  EndJacobian& own = dOwn_[i];
  EndJacobian& first = dJoint_[i];
  own.block<3, 3>(0, 0) += Eigen::Matrix3d::Identity() * positionRow_;
  first.block<3, 3>(0, 0) -= Eigen::Matrix3d::Identity() * positionRow_;
  for (int j = 0; j < 3; ++j) {
    first.block<1, 4>(3 + j, 6) += g[j].derivatives().head<4>().transpose();
    own.block<1, 4>(3 + j, 6) += g[j].derivatives().tail<4>().transpose();
  }
  own.block<1, 4>(6, 6) = 2.0 * d.s.q.transpose();
}

// One tile's derivatives: the first site's rows by every side of site `tile.columnSite`, a further
// site's rows by its own first side, or by the first site's.
void NodeEquations::chainTile(const Tile& tile, Eigen::Ref<Eigen::MatrixXd> out) const {
  const std::vector<int>& points = node_.columns[tile.columnSite];
  if (tile.rowSite == 0) {
    for (std::size_t k = 0; k < sides_.size(); ++k)
      if (sides_[k].site == tile.columnSite) chainSide(*sides_[k].side.basis, dFirst_[k], points, out);
  } else if (tile.columnSite == tile.rowSite) {
    chainSide(*site(tile.rowSite).side.basis, dOwn_[tile.rowSite], points, out);
  } else {
    chainSide(*site(0).side.basis, dJoint_[tile.rowSite], points, out);
  }
}

void NodeEquations::scatter(Eigen::VectorXd& residual, Eigen::MatrixXd* block, const ItemLayout* layout) const {
  for (std::size_t i = 0; i < node_.ends.size(); ++i) residual.segment<7>(s_.siteRow(node_.ends[i])) = f_.segment<7>(7 * i);
  if (!block) return;
  block->setZero(7, static_cast<Eigen::Index>(layout->width));
  for (const Tile& tile : layout->tiles)
    chainTile(tile, block->middleCols(static_cast<Eigen::Index>(tile.column), static_cast<Eigen::Index>(tile.cols.size())));
}

}  // namespace

void DiscreteStructure::interiorBlock(const DiscreteRod& rod, int j, const Eigen::VectorXd& x, double load,
                                      Eigen::VectorXd& residual, Eigen::MatrixXd* block) const {
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
  block->resize(7, 7 * b.count);
  for (int k = 0; k < b.count; ++k) {
    block->middleCols<3>(7 * k) = d.middleCols<3>(0) * b.d1[k] + d.middleCols<3>(3) * b.d2[k];
    block->middleCols<4>(7 * k + 3) =
        d.middleCols<4>(6) * b.value[k] + d.middleCols<4>(10) * b.d1[k] + d.middleCols<4>(14) * b.d2[k];
  }
}

void DiscreteStructure::nodeBlock(const Node& node, const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                                  Eigen::MatrixXd* block, const ItemLayout* layout) const {
  NodeEquations equations(*this, node, x, block != nullptr);
  equations.evaluate(load);
  equations.scatter(residual, block, layout);
}

std::vector<int> endFunctions(const Basis& b) {
  std::vector<int> k;
  for (int i = 0; i < b.count; ++i)
    if (b.value[i] != 0.0 || b.d1[i] != 0.0) k.push_back(i);
  return k;
}

namespace {

// Which entries of a node's tile can be non-zero (column-major, 7 rows by the tile's columns). The
// support, joint and unit-norm rows depend on the sites' positions and rotations only (the site's
// own control point, the one with a non-zero value there); force and moment balance on every
// site's position, tangent, rotation and its derivative.
std::vector<char> tileMask(const DiscreteStructure& s, const Node& node, const Tile& tile) {
  const Site& columnSite = node.ends[tile.columnSite];
  const int own = s.rodOf(columnSite).point(columnSite);
  const std::vector<int>& points = node.columns[tile.columnSite];
  std::vector<char> mask(7 * tile.cols.size());
  for (std::size_t c = 0; c < tile.cols.size(); ++c) {
    const bool atSite = points[c / 7] == own, rotationColumn = c % 7 >= 3;
    for (std::size_t local = 0; local < 7; ++local) {
      const bool rotationRow = local >= 3;  // rows 3..6: moments, rotations, unit norm
      const bool balance = tile.rowSite == 0 && ((local < 3 && !node.support) ||
                                                 (local >= 3 && local < 6 && node.support != SupportKind::Clamped));
      const bool tied = local == 6 ? tile.columnSite == tile.rowSite : (tile.columnSite == 0 || tile.columnSite == tile.rowSite);
      mask[7 * c + local] = balance || (tied && atSite && rotationColumn == rotationRow);
    }
  }
  return mask;
}

// A node's tiles, in the order of their columns' sites (the order in which entries two tiles share,
// as when a one-span rod's ends meet, are summed): the first site's rows by site j's columns, then
// site j's rows by its own columns; site j's rows by the first site's columns come with the first's.
std::vector<Tile> nodeTiles(const DiscreteStructure& s, const Node& node) {
  std::vector<Tile> tiles;
  auto add = [&](std::size_t rowSite, std::size_t columnSite) {
    Tile& t = tiles.emplace_back();
    t.rowSite = rowSite, t.columnSite = columnSite;
    t.firstRow = s.siteRow(node.ends[rowSite]);
    const Site& e = node.ends[columnSite];
    for (int point : node.columns[columnSite])
      for (int c = 0; c < 7; ++c) t.cols.push_back(s.rodOf(e).offset + 7 * static_cast<std::size_t>(point) + c);
    t.nonzero = tileMask(s, node, t);
  };
  add(0, 0);
  for (std::size_t i = 1; i < node.ends.size(); ++i) add(i, 0);
  for (std::size_t j = 1; j < node.ends.size(); ++j) add(0, j), add(j, j);
  return tiles;
}

ItemLayout interiorLayout(const DiscreteRod& rod, int j) {
  Tile t;
  t.firstRow = rod.row(j);
  appendColumns(rod, rod.basis[j], allFunctions(rod.basis[j]), t.cols);
  // The unit-norm row (6) does not depend on positions.
  t.nonzero.assign(7 * t.cols.size(), 1);
  for (std::size_t c = 0; c < t.cols.size(); ++c) t.nonzero[7 * c + 6] = c % 7 >= 3;
  ItemLayout layout;
  layout.tiles.push_back(std::move(t));
  return layout;
}

}  // namespace

void DiscreteStructure::buildLayouts() {
  layouts.assign(items.size(), {});
  for (std::size_t i = 0; i < items.size(); ++i) {
    ItemLayout& layout = layouts[i];
    if (items[i].rod >= 0) layout = interiorLayout(rods[items[i].rod], items[i].point);
    else layout.tiles = nodeTiles(*this, nodes[items[i].point]);
    for (Tile& t : layout.tiles) t.column = layout.width, layout.width += t.cols.size();
  }
  // The pattern from every tile (duplicates, as when a closed rod's two ends share a control
  // point, merge), then each tile entry's position in it (-1: structurally zero).
  std::vector<Eigen::Triplet<double>> entries;
  for (const ItemLayout& layout : layouts)
    for (const Tile& t : layout.tiles)
      for (std::size_t c = 0, k = 0; c < t.cols.size(); ++c)
        for (std::size_t r = 0; r < 7; ++r, ++k)
          if (t.nonzero[k]) entries.emplace_back(static_cast<int>(t.firstRow + r), static_cast<int>(t.cols[c]), 0.0);
  if (entries.size() >= static_cast<std::size_t>(std::numeric_limits<int>::max()))
    fail("", "the Jacobian would have " + std::to_string(entries.size()) + " entries, more than this solver handles (2^31)");
  pattern.resize(static_cast<Eigen::Index>(unknowns), static_cast<Eigen::Index>(unknowns));
  pattern.setFromTriplets(entries.begin(), entries.end());
  pattern.makeCompressed();
  slots.clear();
  for (ItemLayout& layout : layouts) {
    layout.firstSlot = slots.size();
    for (const Tile& t : layout.tiles)
      for (std::size_t c = 0, k = 0; c < t.cols.size(); ++c) {
        const int* begin = pattern.innerIndexPtr() + pattern.outerIndexPtr()[t.cols[c]];
        const int* end = pattern.innerIndexPtr() + pattern.outerIndexPtr()[t.cols[c] + 1];
        for (std::size_t r = 0; r < 7; ++r, ++k)
          slots.push_back(t.nonzero[k] ? static_cast<int>(std::lower_bound(begin, end, static_cast<int>(t.firstRow + r)) -
                                                          pattern.innerIndexPtr())
                                       : -1);
      }
  }
}

}  // namespace rodfab::mechanics::detail
