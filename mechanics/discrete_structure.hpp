// The discretized rod structure behind StaticProblem: each rod's solver basis, collocation points
// and pointwise constants, the nodes (rod ends with their joint, support and load conditions), and
// the residual and Jacobian blocks they contribute. Internal to mechanics/.
#pragma once

#include "mechanics/cosserat_point.hpp"
#include "mechanics/mechanics.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace rodfab::mechanics::detail {

// Non-zero (rational) basis functions and their first two derivatives at one parameter.
struct Basis {
  int first = 0;  // index of the first non-zero function
  int count = 0;  // degree + 1
  std::array<double, geometry::kMaxDegree + 1> value{}, d1{}, d2{};
};

Basis rationalBasis(const geometry::NurbsCurve& curve, double u);

// The automatic span count of a rebuilt rod (discretization.cpp); above kMaxSpansPerRod when the
// degree converges too slowly for `tolerance`.
int automaticSpans(const geometry::Rod& rod, int degree, double tolerance);

// One end of one rod, by index: a geometry::RodEndRef once resolved against the structure.
struct ResolvedEnd {
  int rod = 0;
  int end = 0;  // 0 start, 1 end
  bool operator<(const ResolvedEnd& o) const { return rod != o.rod ? rod < o.rod : end < o.end; }
  bool operator==(const ResolvedEnd& o) const { return rod == o.rod && end == o.end; }
};

// Rod ends that share a position: a free end, a support, or a joint (two or more ends).
struct Node {
  std::vector<ResolvedEnd> ends;  // the first end's slot carries the balance / support rows
  std::optional<geometry::SupportKind> support;  // none: free (force and moment balance)
  std::string supportPath;
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero(), rotation = Eigen::Vector3d::Zero();
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), moment = Eigen::Vector3d::Zero();
  // Reference data: the first end's position and unit quaternion; per further end its offset from
  // the first end and the relative rotation conj(q_first) q_end to keep.
  Eigen::Vector3d position0;
  Eigen::Vector4d quaternion0;
  std::vector<Eigen::Vector3d> offsets0;
  std::vector<Eigen::Vector4d> relative0;
};

// One rod on its solver basis.
struct DiscreteRod {
  std::string name, path;
  geometry::NurbsCurve curve;  // refined; its control points are the reference positions
  int degree = 0, count = 0;
  bool rebuilt = false;        // on a uniform B-spline of its own, not the design's basis
  int spans = 0;               // rebuilt: spans; design basis: solver spans per design span
  std::size_t offset = 0;      // first unknown
  std::vector<double> tau;     // Greville abscissae
  std::vector<Basis> basis;    // at tau
  std::vector<PointConstants> constants;  // at tau
  double length = 0.0, forceScale = 1.0, momentScale = 1.0;
  const geometry::Rod* source = nullptr;

  std::size_t row(int j) const { return offset + 7 * static_cast<std::size_t>(j); }
  int point(int end) const { return end == 0 ? 0 : count - 1; }
};

// Interpolated values of the local state at one parameter from x.
struct LocalState {
  Eigen::Vector3d r, dr, ddr;
  Eigen::Vector4d q, dq, ddq;
};

LocalState localState(const DiscreteRod& rod, const Basis& b, const Eigen::VectorXd& x);

// Control values (rows) whose spline takes the rows of `samples` at the rod's collocation points;
// none if the collocation matrix is singular.
std::optional<Eigen::MatrixXd> interpolateAtCollocationPoints(const DiscreteRod& rod, const Eigen::MatrixXd& samples);

// Control points (indices into a basis' functions) on which a rod end's position and tangent
// depend: those with a non-zero value or first derivative there (2 of degree + 1 at a clamped end).
std::vector<int> endFunctions(const Basis& b);

// One block of rows: an interior collocation point of a rod, or a node (rod < 0, point = node index).
struct WorkItem {
  int rod, point;
};

// Where one work item's dense block of derivatives sits in the Jacobian: its rows, its columns,
// which of its entries can be non-zero (column-major), and the first of its rows.size() *
// cols.size() value positions (column-major, -1 for entries that are always zero) in `slots`.
struct ItemLayout {
  std::vector<std::size_t> rows, cols;
  std::vector<char> nonzero;
  std::size_t firstSlot = 0;
};

struct DiscreteStructure {
  std::string source;
  std::vector<DiscreteRod> rods;
  std::vector<Node> nodes;
  std::vector<WorkItem> items;  // every interior collocation point, then every node
  std::vector<ItemLayout> layouts;  // per item
  std::vector<int> slots;  // positions in the Jacobian's value array, per item (ItemLayout)
  Eigen::SparseMatrix<double> pattern;  // the Jacobian's sparsity, values zero
  std::size_t unknowns = 0, joints = 0, supports = 0;
  double size = 1.0;  // structure's bounding-box diagonal
  Eigen::VectorXd reference;
  // The design's mechanics block with every reference by point turned into one by rod name and
  // end, so it still resolves once the ends have moved (deformedStructure).
  geometry::MechanicsSpec spec;
  Discretization discretization;  // as resolved (perRod filled)

  const DiscreteRod& rodOf(const ResolvedEnd& e) const { return rods[e.rod]; }
  const Basis& endBasis(const ResolvedEnd& e) const { const DiscreteRod& r = rods[e.rod]; return r.basis[r.point(e.end)]; }
  const PointConstants& endConstants(const ResolvedEnd& e) const {
    const DiscreteRod& r = rods[e.rod];
    return r.constants[r.point(e.end)];
  }
  std::size_t endRow(const ResolvedEnd& e) const { return rodOf(e).row(rodOf(e).point(e.end)); }

  [[noreturn]] void fail(const std::string& path, const std::string& message) const;

  // discretization.cpp: appends rod `index` of `structure` with its unknowns and reference state.
  void buildRod(const geometry::RodStructure& structure, std::size_t index, const Discretization& discretization);
  // nodes.cpp: joints, supports and loads; throws MechanicsError for unresolvable or unsupported parts.
  void buildNodes(const geometry::RodStructure& structure);
  ResolvedEnd resolve(const geometry::RodEndRef& ref, const geometry::RodStructure& structure) const;
  void keepSpec(const geometry::RodStructure& structure);
  // equations.cpp: the rows and columns of every work item and the Jacobian's pattern.
  void buildLayouts();
  // The residual rows of one work item and, with `block`, their derivatives (rows by columns of
  // the item's layout).
  void interiorBlock(const DiscreteRod& rod, int j, const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                     Eigen::MatrixXd* block) const;
  void nodeBlock(const Node& node, const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                 Eigen::MatrixXd* block) const;
};

std::string format(double v);
std::string format(const Eigen::Vector3d& v);

}  // namespace rodfab::mechanics::detail
