// The discretized rod structure behind StaticProblem: each rod's solver basis, collocation points
// and pointwise constants, the nodes (rod ends with their joint, support and load conditions), and
// the residual and Jacobian blocks they contribute. Internal to mechanics/.
#pragma once

#include "mechanics/cosserat_point.hpp"
#include "mechanics/mechanics.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <algorithm>
#include <array>
#include <utility>
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
// The same from the span that ends at u (the limit from below): differs at a C0 knot.
Basis rationalBasisBelow(const geometry::NurbsCurve& curve, double u);

// The spans collocation at `degree` needs on `rod` for the relative accuracy `tolerance` by the a
// priori model of solver_basis.cpp (locking of slender and curved rods, steep E(s)), unrounded.
double aPrioriSpans(const geometry::Rod& rod, int degree, double tolerance);
// The automatic span count of a rebuilt rod (solver_basis.cpp); above kMaxSpansPerRod when the
// degree converges too slowly for `tolerance`.
int automaticSpans(const geometry::Rod& rod, int degree, double tolerance);

// A place on one rod where a node acts: one of its ends, or one of its interior sites, where the
// solver basis has a C0 knot (multiplicity = degree) whose control point interpolates r and q: the
// rod's two sides meet there, and n and m may jump by the node's point force and moment.
struct Site {
  static constexpr int kInterior = 2;
  int rod = 0;
  int end = 0;    // 0 start, 1 end, kInterior: the rod's interior site `index`
  int index = 0;  // with kInterior
};

// A reference resolved on the design, before discretization: a rod end, or a rod's interior point.
struct Place {
  int rod = 0;
  int end = 0;     // 0 start, 1 end, Site::kInterior
  double u = 0.0;  // with Site::kInterior
};

// One side of a site: the basis and constants there (from below or above at an interior site),
// and the sign its internal force takes in the node's balance: + n at a start (or the side above
// an interior site), - n at an end (or the side below).
struct SiteSide {
  const Basis* basis;
  const PointConstants* constants;
  double sign;
};

// The one or two sides of a site, without allocating (node equations are evaluated often).
struct SiteSides {
  std::array<SiteSide, 2> sides;
  int count = 0;
  const SiteSide* begin() const { return sides.data(); }
  const SiteSide* end() const { return sides.data() + count; }
};

// What acts at a node besides its sites: its support or loads, and its first site's reference state.
struct NodeConditions {
  std::optional<SupportKind> support;  // none: free (force and moment balance)
  std::string supportPath;
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero(), rotation = Eigen::Vector3d::Zero();
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), moment = Eigen::Vector3d::Zero();  // dead, in space
  // Follower loads: given in space for the drawn shape (followerForce0, followerMoment0), and the
  // same in the first site's material frame (R0^T times them), turned by its rotation R(q).
  Eigen::Vector3d followerForce0 = Eigen::Vector3d::Zero(), followerMoment0 = Eigen::Vector3d::Zero();
  Eigen::Vector3d followerForce = Eigen::Vector3d::Zero(), followerMoment = Eigen::Vector3d::Zero();
  bool hasFollower = false;
  // The first site's reference position and unit quaternion.
  Eigen::Vector3d position0;
  Eigen::Vector4d quaternion0;
};

// Rod sites that share a position: a free end, a support, a load point, or a joint (two or more sites).
struct Node : NodeConditions {
  std::vector<Site> ends;  // the first site's slot carries the balance / support rows
  // Reference data per further site: its offset from the first and the relative rotation
  // conj(q_first) q_site to keep.
  std::vector<Eigen::Vector3d> offsets0;
  std::vector<Eigen::Vector4d> relative0;
  // Per site: the control points whose columns its rows use (DiscreteStructure::siteColumns).
  std::vector<std::vector<int>> columns;

  // The same node with only its first site and site i (i > 0), or the first alone (i = 0): the
  // part of the node through which site i's own constants act (modulus_sensitivity.cpp).
  Node pairWith(std::size_t i) const {
    Node out;
    static_cast<NodeConditions&>(out) = *this;
    out.ends.push_back(ends[0]);
    out.columns.push_back(columns[0]);
    if (i == 0) return out;
    out.ends.push_back(ends[i]);
    out.columns.push_back(columns[i]);
    out.offsets0.push_back(offsets0[i - 1]);
    out.relative0.push_back(relative0[i - 1]);
    return out;
  }
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
  // Interior sites (T-joints, loads and supports inside the rod): their parameters (increasing),
  // the control point at each (its tau), and the basis and constants there from below (from
  // above they are basis and constants at that point).
  std::vector<double> sites;
  std::vector<int> sitePoints;
  std::vector<Basis> siteBelow;
  std::vector<PointConstants> siteBelowConstants;
  double length = 0.0, forceScale = 1.0, momentScale = 1.0;
  const geometry::Rod* source = nullptr;

  std::size_t row(int j) const { return offset + 7 * static_cast<std::size_t>(j); }
  int point(const Site& site) const { return site.end == Site::kInterior ? sitePoints[site.index] : site.end == 0 ? 0 : count - 1; }
  bool isSitePoint(int j) const { return std::binary_search(sitePoints.begin(), sitePoints.end(), j); }
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
// depend: those with a non-zero value or first derivative there (2 of degree + 1 at a clamped end
// or on one side of a C0 knot).
std::vector<int> endFunctions(const Basis& b);

// One block of rows: an interior collocation point of a rod, or a node (rod < 0, point = node index).
struct WorkItem {
  int rod, point;
};

// One dense tile of a work item's derivatives: 7 rows (a collocation point's, or one site's of a
// node) by the columns of control points (7 each). An interior point has one tile; a node one per
// pair of sites that are coupled: its first site's rows by every site's columns, and each further
// site's rows by its own and the first site's columns (joint conditions tie each end to the first).
struct Tile {
  std::size_t firstRow = 0;  // rows firstRow .. firstRow + 6
  std::vector<std::size_t> cols;
  std::vector<char> nonzero;                // which entries can be non-zero (7 x cols, column-major)
  std::size_t rowSite = 0, columnSite = 0;  // in a node: whose rows and whose columns
  std::size_t column = 0;                   // its first column in the item's block
};

// Where one work item's derivatives sit in the Jacobian: its tiles side by side in one block of 7
// rows and `width` columns, and the first of the block's 7 * width value positions (column-major,
// -1 for entries that are always zero) in `slots`.
struct ItemLayout {
  std::vector<Tile> tiles;
  std::size_t width = 0;
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
  MechanicsSpec spec;
  Discretization discretization;  // as resolved (perRod filled)

  // Pre-pass (nodes.cpp), before the rods are discretized: per design rod the parameters of its
  // interior sites and their design points, and the rod ends found on other rods' interiors.
  std::vector<std::vector<double>> interiorSites;
  std::vector<std::vector<geometry::Vec3>> interiorPoints;
  std::vector<std::pair<int, Place>> tJoints;  // (end site number 2 rod + end, interior place)
  std::vector<int> siteBase;  // per rod: number of its first interior site

  const DiscreteRod& rodOf(const Site& e) const { return rods[e.rod]; }
  SiteSides sides(const Site& e) const;
  // The site's control points whose columns its node rows use (sorted).
  std::vector<int> siteColumns(const Site& e) const;
  const Basis& siteBasis(const Site& e) const { const DiscreteRod& r = rods[e.rod]; return r.basis[r.point(e)]; }
  std::size_t siteRow(const Site& e) const { return rodOf(e).row(rodOf(e).point(e)); }

  [[noreturn]] void fail(const std::string& path, const std::string& message) const;

  // discretization.cpp: appends rod `index` of `structure` with its unknowns and reference state.
  void buildRod(const Design& structure, std::size_t index, const Discretization& discretization);
  // nodes.cpp: the interior sites (before buildRod), then joints, supports and loads; throws
  // MechanicsError for unresolvable or unsupported parts.
  void findInteriorSites(const Design& structure);
  void buildNodes(const Design& structure);
  void refuseAbsurdLoads(const Design& structure) const;
  Place locate(const RodEndRef& ref, const Design& structure) const;
  int siteNumber(const Place& place) const;  // 2 rod + end, or after all ends the interior sites in order
  Site siteOf(int number) const;
  void keepSpec(const Design& structure);
  // equations.cpp: the rows and columns of every work item and the Jacobian's pattern.
  void buildLayouts();
  // The residual rows of one work item and, with `block`, their derivatives (the item's layout:
  // 7 rows by its tiles' columns; a node's tiles are those of its layout).
  void interiorBlock(const DiscreteRod& rod, int j, const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                     Eigen::MatrixXd* block) const;
  void nodeBlock(const Node& node, const Eigen::VectorXd& x, double load, Eigen::VectorXd& residual,
                 Eigen::MatrixXd* block, const ItemLayout* layout = nullptr) const;
};

std::string format(double v);
std::string format(const Eigen::Vector3d& v);

}  // namespace rodfab::mechanics::detail
