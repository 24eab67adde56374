// Nodes of the structure: rod sites (ends and interior points) grouped into joints (inferred by
// position or listed), the supports and loads acting on them, and their reference data for the
// node equations. Interior sites are found first, on the design, because each becomes a C0 knot of
// its rod's solver basis.
#include "mechanics/discrete_structure.hpp"
#include "mechanics/section_properties.hpp"

#include "common/quoted_text.hpp"

#include <algorithm>
#include <limits>
#include <map>
#include <numeric>

namespace rodfab::mechanics::detail {

using geometry::Vec3;

namespace {

// Union-find over site numbers.
class SiteSets {
public:
  explicit SiteSets(int count) : parent_(count) { std::iota(parent_.begin(), parent_.end(), 0); }
  int find(int i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  void unite(int a, int b) {
    a = find(a), b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

private:
  std::vector<int> parent_;
};

Vec3 designEnd(const geometry::Rod& rod, int end) {
  const geometry::NurbsCurve& c = rod.centerline();
  return c.point(end == 0 ? c.domainBegin() : c.domainEnd());
}

// The box of a rod's control points (which holds its centerline), grown by `margin`.
Eigen::AlignedBox3d controlBox(const geometry::Rod& rod, double margin) {
  Eigen::AlignedBox3d box;
  for (const Vec3& p : rod.centerline().points()) box.extend(p);
  box.min().array() -= margin;
  box.max().array() += margin;
  return box;
}

// A rod's point at parameter u: its start or end when within the joint tolerance of it (so a
// site never makes a piece shorter than that), else an interior place.
Place placeOnRod(const Design& structure, int rod, double u) {
  const geometry::Rod& r = structure.rods[rod];
  const Vec3 p = r.centerline().point(u);
  for (int end = 0; end < 2; ++end)
    if ((p - designEnd(r, end)).norm() <= structure.mechanics.jointTolerance) return {rod, end, 0.0};
  return {rod, Site::kInterior, u};
}

}  // namespace

SiteSides DiscreteStructure::sides(const Site& e) const {
  const DiscreteRod& r = rods[e.rod];
  const int j = r.point(e);
  SiteSides out;
  if (e.end != Site::kInterior) {
    out.sides[0] = {&r.basis[j], &r.constants[j], e.end == 0 ? 1.0 : -1.0};
    out.count = 1;
  } else {
    out.sides[0] = {&r.siteBelow[e.index], &r.siteBelowConstants[e.index], -1.0};
    out.sides[1] = {&r.basis[j], &r.constants[j], 1.0};
    out.count = 2;
  }
  return out;
}

std::vector<int> DiscreteStructure::siteColumns(const Site& e) const {
  std::vector<int> points;
  for (const SiteSide& side : sides(e))
    for (int k : endFunctions(*side.basis)) points.push_back(side.basis->first + k);
  std::sort(points.begin(), points.end());
  points.erase(std::unique(points.begin(), points.end()), points.end());
  return points;
}

Place DiscreteStructure::locate(const RodEndRef& ref, const Design& structure) const {
  const double tolerance = structure.mechanics.jointTolerance;
  if (!ref.point) {
    for (std::size_t i = 0; i < structure.rods.size(); ++i) {
      if (structure.rods[i].name() != ref.rod) continue;
      if (!ref.parameter) return {static_cast<int>(i), ref.end == RodEnd::Start ? 0 : 1, 0.0};
      const geometry::NurbsCurve& c = structure.rods[i].centerline();
      if (!(*ref.parameter >= c.domainBegin() && *ref.parameter <= c.domainEnd()))
        fail(ref.path + ".parameter", "u = " + format(*ref.parameter) + " lies outside rod \"" + ref.rod +
                                          "\"'s centerline domain [" + format(c.domainBegin()) + ", " + format(c.domainEnd()) + "]");
      return placeOnRod(structure, static_cast<int>(i), *ref.parameter);
    }
    fail(ref.path + ".rod", "no rod is named " + common::quotedFromFile(ref.rod, 64));
  }
  // The nearest rod end within the tolerance, else the nearest interior point.
  Place best;
  double bestDistance = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < structure.rods.size(); ++i)
    for (int end = 0; end < 2; ++end) {
      const double d = (designEnd(structure.rods[i], end) - *ref.point).norm();
      if (d < bestDistance) bestDistance = d, best = {static_cast<int>(i), end, 0.0};
    }
  if (bestDistance <= tolerance) return best;
  Place inner;
  double innerDistance = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < structure.rods.size(); ++i) {
    if (!controlBox(structure.rods[i], tolerance).contains(*ref.point)) continue;
    const geometry::ClosestPoint cp = structure.rods[i].closestPoint(*ref.point);
    if (cp.distance < innerDistance) innerDistance = cp.distance, inner = {static_cast<int>(i), Site::kInterior, cp.u};
  }
  if (innerDistance <= tolerance) return placeOnRod(structure, inner.rod, inner.u);
  fail(ref.path + ".point", "no rod lies within joint_tolerance (" + format(tolerance) + " mm) of " + format(*ref.point) +
                                "; the nearest rod end is the " + (best.end ? "end" : "start") + " of rod \"" +
                                structure.rods[best.rod].name() + "\", " + format(bestDistance) + " mm away");
}

namespace {

// u moved onto a C0 knot of the curve (multiplicity >= degree) whose point lies within `tolerance`
// of u's, if there is one: there the centerline may turn (a deformed design's T-joint does), which
// only a site's C0 knot of the solver basis follows.
double onC0Knot(const geometry::NurbsCurve& c, double u, double tolerance) {
  const auto& k = c.knots();
  const std::size_t n = c.points().size();
  const int p = c.degree();
  for (std::size_t i = p + 1; i < n;) {
    std::size_t m = 1;
    while (i + m < n && k[i + m] == k[i]) ++m;
    if (m >= static_cast<std::size_t>(p) && (c.point(k[i]) - c.point(u)).norm() <= tolerance) return k[i];
    i += m;
  }
  return u;
}

// Rod ends that lie on another rod's interior (within the tolerance, away from that rod's ends):
// T-joints. Only rods whose control box holds the end are searched.
std::vector<std::pair<int, Place>> findTJoints(const Design& structure) {
  const double tolerance = structure.mechanics.jointTolerance;
  std::vector<Eigen::AlignedBox3d> boxes;
  for (const geometry::Rod& rod : structure.rods) boxes.push_back(controlBox(rod, tolerance));
  std::vector<std::pair<int, Place>> found;
  for (std::size_t a = 0; a < structure.rods.size(); ++a)
    for (int end = 0; end < 2; ++end) {
      const Vec3 p = designEnd(structure.rods[a], end);
      for (std::size_t b = 0; b < structure.rods.size(); ++b) {
        if (b == a || !boxes[b].contains(p)) continue;
        const geometry::Rod& rod = structure.rods[b];
        if ((p - designEnd(rod, 0)).norm() <= tolerance || (p - designEnd(rod, 1)).norm() <= tolerance) continue;
        const geometry::ClosestPoint cp = rod.closestPoint(p);
        if (cp.distance <= tolerance)
          found.emplace_back(static_cast<int>(2 * a + end), placeOnRod(structure, static_cast<int>(b), cp.u));
      }
    }
  return found;
}

}  // namespace

// Every interior place the design refers to (T-joints, listed joints, supports, loads), per rod in
// increasing parameter; places within the joint tolerance of each other are one site.
void DiscreteStructure::findInteriorSites(const Design& structure) {
  const MechanicsSpec& spec = structure.mechanics;
  std::vector<std::vector<double>> wanted(structure.rods.size());
  auto want = [&](const Place& place) {
    if (place.end == Site::kInterior) wanted[place.rod].push_back(place.u);
  };
  if (spec.inferJoints) tJoints = findTJoints(structure);
  for (const auto& [end, place] : tJoints) want(place);
  for (const auto& joint : spec.joints)
    for (const auto& ref : joint) want(locate(ref, structure));
  for (const auto& support : spec.supports) want(locate(support.at, structure));
  for (const auto& load : spec.loads) want(locate(load.at, structure));
  interiorSites.assign(structure.rods.size(), {});
  interiorPoints.assign(structure.rods.size(), {});
  siteBase.assign(structure.rods.size(), 0);
  int next = static_cast<int>(2 * structure.rods.size());
  for (std::size_t r = 0; r < structure.rods.size(); ++r) {
    const geometry::NurbsCurve& c = structure.rods[r].centerline();
    for (double& u : wanted[r]) u = onC0Knot(c, u, spec.jointTolerance);
    std::sort(wanted[r].begin(), wanted[r].end());
    for (double u : wanted[r]) {
      const Vec3 p = c.point(u);
      if (!interiorPoints[r].empty() && (p - interiorPoints[r].back()).norm() <= spec.jointTolerance) continue;
      interiorSites[r].push_back(u);
      interiorPoints[r].push_back(p);
    }
    // Every site starts a piece of at least one span: bounded like the spans.
    if (interiorSites[r].size() >= static_cast<std::size_t>(kMaxSpansPerRod))
      fail("rods[" + std::to_string(r) + "]", "more than " + std::to_string(kMaxSpansPerRod - 1) +
                                                  " interior places (T-joints, loads, supports) on one rod");
    siteBase[r] = next;
    next += static_cast<int>(interiorSites[r].size());
  }
}

int DiscreteStructure::siteNumber(const Place& place) const {
  if (place.end != Site::kInterior) return 2 * place.rod + place.end;
  // The site nearest to the place (findInteriorSites made one within the tolerance).
  const geometry::NurbsCurve& c = rods[place.rod].source->centerline();
  const Vec3 p = c.point(place.u);
  const std::vector<Vec3>& points = interiorPoints[place.rod];
  int best = 0;
  for (int i = 1; i < static_cast<int>(points.size()); ++i)
    if ((points[i] - p).norm() < (points[best] - p).norm()) best = i;
  return siteBase[place.rod] + best;
}

Site DiscreteStructure::siteOf(int number) const {
  if (number < static_cast<int>(2 * rods.size())) return {number / 2, number % 2, 0};
  const int rod = static_cast<int>(std::upper_bound(siteBase.begin(), siteBase.end(), number) - siteBase.begin()) - 1;
  return {rod, Site::kInterior, number - siteBase[rod]};
}

namespace {

// Where a place is on the drawn design.
Vec3 placePoint(const Design& structure, const Place& place) {
  const geometry::Rod& rod = structure.rods[static_cast<std::size_t>(place.rod)];
  return place.end == Site::kInterior ? rod.centerline().point(place.u) : designEnd(rod, place.end);
}

const Vec3& endPoint(const DiscreteRod& rod, int end) { return end == 0 ? rod.curve.points().front() : rod.curve.points().back(); }

// A rod whose two ends the tolerance joins is a closed loop only if they nearly meet (within a
// hundredth of its length); otherwise the tolerance spans the rod itself (a 1 um rod at the default
// 1 um, or a tolerance of metres) and joining would turn it into a ring with its load lost.
void refuseSelfJoinedRods(const DiscreteStructure& s, double tolerance, SiteSets& sets) {
  for (int r = 0; r < static_cast<int>(s.rods.size()); ++r) {
    const DiscreteRod& rod = s.rods[r];
    const double gap = (endPoint(rod, 0) - endPoint(rod, 1)).norm();
    if (sets.find(2 * r) == sets.find(2 * r + 1) && gap > 0.01 * rod.length)
      s.fail(rod.path, "its two ends, " + format(gap) + " mm apart on a rod " + format(rod.length) +
                           " mm long, would be joined to each other by joint_tolerance " + format(tolerance) +
                           " mm (directly or through other rods' ends); give a joint_tolerance well below the rod's length");
  }
}

// Joins the rod sites the design joins: all ends within the joint tolerance of each other and the
// T-joints, or the listed groups.
void joinSites(const DiscreteStructure& s, const Design& structure, SiteSets& sets) {
  const MechanicsSpec& spec = structure.mechanics;
  const int endCount = static_cast<int>(2 * s.rods.size());
  if (spec.inferJoints) {
    // Sort ends by x so only neighbours within the tolerance are compared.
    std::vector<int> order(endCount);
    std::iota(order.begin(), order.end(), 0);
    auto at = [&](int i) -> const Vec3& { return endPoint(s.rods[i / 2], i % 2); };
    std::sort(order.begin(), order.end(), [&](int a, int b) { return at(a).x() < at(b).x() || (at(a).x() == at(b).x() && a < b); });
    for (int a = 0; a < endCount; ++a)
      for (int b = a + 1; b < endCount && at(order[b]).x() - at(order[a]).x() <= spec.jointTolerance; ++b)
        if ((at(order[a]) - at(order[b])).norm() <= spec.jointTolerance) sets.unite(order[a], order[b]);
    for (const auto& [end, place] : s.tJoints) sets.unite(end, s.siteNumber(place));
    refuseSelfJoinedRods(s, spec.jointTolerance, sets);
    return;
  }
  std::map<int, std::string> listed;
  for (std::size_t j = 0; j < spec.joints.size(); ++j) {
    if (spec.joints[j].empty()) continue;  // the reader refuses them; a joint built in code may be
    const Vec3 meeting = placePoint(structure, s.locate(spec.joints[j][0], structure));
    for (std::size_t k = 0; k < spec.joints[j].size(); ++k) {
      const Place place = s.locate(spec.joints[j][k], structure);
      const int site = s.siteNumber(place);
      const std::string where = spec.joints[j][k].path;
      if (auto [it, fresh] = listed.emplace(site, where); !fresh)
        s.fail(where, "this rod end or point is already in a joint (" + it->second + ")");
      // The joint ties its members' positions: members apart would be held apart by nothing (no link
      // carries the moment of the gap), an answer no structure gives.
      if (const double gap = (placePoint(structure, place) - meeting).norm(); gap > spec.jointTolerance)
        s.fail(where, "lies " + format(gap) + " mm from the joint's first member (" + spec.joints[j][0].path +
                          "): a joint's members must meet, within joint_tolerance " + format(spec.jointTolerance) +
                          " mm; join places apart with a rod between them");
      sets.unite(s.siteNumber(s.locate(spec.joints[j][0], structure)), site);
    }
  }
}

}  // namespace

void DiscreteStructure::keepSpec(const Design& structure) {
  spec = structure.mechanics;
  auto byName = [&](RodEndRef& ref) {
    if (!ref.point) return;
    const Place place = locate(ref, structure);
    ref.rod = rods[place.rod].name;
    if (place.end == Site::kInterior) {
      const Site site = siteOf(siteNumber(place));
      ref.parameter = rods[site.rod].sites[site.index];
    } else {
      ref.end = place.end == 0 ? RodEnd::Start : RodEnd::End;
    }
    ref.point.reset();
  };
  for (auto& joint : spec.joints)
    for (auto& ref : joint) byName(ref);
  for (auto& support : spec.supports) byName(support.at);
  for (auto& load : spec.loads) byName(load.at);
}

namespace {

// The JSON path of the load or support whose place `at` is ("mechanics.loads[0].at" -> "mechanics.loads[0]").
std::string ownerPath(const RodEndRef& at) {
  return at.path.ends_with(".at") ? at.path.substr(0, at.path.size() - 3) : at.path;
}

}  // namespace

// Loads no rod of the design could bear and support motions far beyond its size, told by their field
// before Newton fails on them ("did not converge beyond load factor 0", naming none, for 1e30 N): a
// force above 1e4 times the stiffest rod's E A, a moment above that times the design's size, a support
// moved 1e4 times the design's size or turned 1e4 rad.
void DiscreteStructure::refuseAbsurdLoads(const Design& structure) const {
  double stiffest = 0.0;  // N: the largest E A of any rod
  for (const geometry::Rod& rod : structure.rods) {
    const std::vector<double>& e = rod.modulus().values();
    stiffest = std::max(stiffest, *std::max_element(e.begin(), e.end()) * sectionProperties(rod.section(), structure.mechanics.poissonRatio).area);
  }
  const double size = structure.bounds().diagonal().norm(), force = 1e4 * stiffest, moment = force * size;
  const auto refuse = [&](const std::string& path, const char* what, double value, double limit, const std::string& unit) {
    if (!(value <= limit))
      fail(path, what + std::string(" of ") + format(value) + " " + unit + " is more than " + format(limit) + " " + unit +
                     " (10,000 times what the stiffest rod, E A = " + format(stiffest) + " N, or the design's " + format(size) +
                     " mm make plausible): no rod of this design bears it (units?)");
  };
  for (const PointLoad& l : structure.mechanics.loads) {
    refuse(ownerPath(l.at) + ".force", "a force", l.force.stableNorm(), force, "N");
    refuse(ownerPath(l.at) + ".moment", "a moment", l.moment.stableNorm(), moment, "N mm");
  }
  for (const DistributedLoad& d : structure.mechanics.distributedLoads)
    refuse(d.path + ".force", "a force per length", d.force.stableNorm(), force / size, "N/mm");
  for (const Support& s : structure.mechanics.supports) {
    refuse(ownerPath(s.at) + ".displacement", "a displacement", s.displacement.stableNorm(), 1e4 * size, "mm");
    refuse(ownerPath(s.at) + ".rotation", "a rotation", s.rotation.stableNorm(), 1e4, "rad");
  }
}

void DiscreteStructure::buildNodes(const Design& structure) {
  const MechanicsSpec& spec = structure.mechanics;
  refuseAbsurdLoads(structure);
  const int siteCount = siteBase.empty() ? 0 : siteBase.back() + static_cast<int>(rods.back().sites.size());
  SiteSets sets(siteCount);
  joinSites(*this, structure, sets);
  std::map<int, std::size_t> nodeOf;
  for (int i = 0; i < siteCount; ++i) {
    auto [it, fresh] = nodeOf.emplace(sets.find(i), nodes.size());
    if (fresh) nodes.emplace_back();
    nodes[it->second].ends.push_back(siteOf(i));
  }
  for (const Node& node : nodes) joints += node.ends.size() > 1;
  auto nodeAt = [&](const RodEndRef& ref) -> Node& { return nodes[nodeOf.at(sets.find(siteNumber(locate(ref, structure))))]; };

  for (const auto& s : spec.supports) {
    Node& node = nodeAt(s.at);
    if (node.support) fail(s.at.path, "this rod end, point (or joint) already has a support (" + node.supportPath + ")");
    node.support = s.kind;
    node.supportPath = s.at.path;
    node.displacement = s.displacement;
    node.rotation = s.rotation;
    ++supports;
  }
  for (const auto& l : spec.loads) {
    Node& node = nodeAt(l.at);
    if (l.follower) {
      node.followerForce0 += l.force;
      node.followerMoment0 += l.moment;
      node.hasFollower = true;
    } else {
      node.force += l.force;
      node.moment += l.moment;
    }
  }
  if (supports == 0)
    fail("mechanics.supports", "no support: the structure could move as a rigid body; clamp or pin at least one rod end");

  // Every connected part of the structure needs a support of its own: joining each rod's sites in
  // the same union-find turns the joints into connected parts.
  for (std::size_t r = 0; r < rods.size(); ++r) {
    sets.unite(static_cast<int>(2 * r), static_cast<int>(2 * r + 1));
    for (std::size_t i = 0; i < rods[r].sites.size(); ++i) sets.unite(static_cast<int>(2 * r), siteBase[r] + static_cast<int>(i));
  }
  std::vector<bool> held(siteCount, false);
  for (const Node& node : nodes)
    if (node.support) held[sets.find(2 * node.ends.front().rod)] = true;
  for (std::size_t r = 0; r < rods.size(); ++r)
    if (!held[sets.find(static_cast<int>(2 * r))])
      fail("mechanics.supports", "rod \"" + rods[r].name + "\" belongs to a part of the structure without any support "
                                 "(it is not joined to a supported rod); support it or join it");

  for (Node& node : nodes) {
    const Site first = node.ends.front();
    const LocalState s0 = localState(rodOf(first), siteBasis(first), reference);
    node.position0 = s0.r;
    node.quaternion0 = s0.q.normalized();
    const Eigen::Matrix3d R0 = rotationNumerator<double>(node.quaternion0);  // |q0| = 1
    node.followerForce = R0.transpose() * node.followerForce0;
    node.followerMoment = R0.transpose() * node.followerMoment0;
    const Eigen::Vector4d conj0(node.quaternion0[0], -node.quaternion0[1], -node.quaternion0[2], -node.quaternion0[3]);
    for (std::size_t i = 1; i < node.ends.size(); ++i) {
      const LocalState s = localState(rodOf(node.ends[i]), siteBasis(node.ends[i]), reference);
      node.offsets0.push_back(s.r - s0.r);
      node.relative0.push_back(quaternionProduct<double>(conj0, s.q.normalized()));
    }
    for (const Site& site : node.ends) node.columns.push_back(siteColumns(site));
  }
}

}  // namespace rodfab::mechanics::detail
