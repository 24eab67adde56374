// Nodes of the structure: rod ends grouped into joints (inferred by position or listed), the
// supports and loads acting on them, and their reference data for the node equations.
#include "mechanics/discrete_structure.hpp"

#include <algorithm>
#include <limits>
#include <map>
#include <numeric>

namespace rodfab::mechanics::detail {

using geometry::Vec3;

namespace {

// Union-find over rod ends, numbered 2 rod + end.
class EndSets {
public:
  explicit EndSets(int count) : parent_(count) { std::iota(parent_.begin(), parent_.end(), 0); }
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

int endIndex(const ResolvedEnd& e) { return 2 * e.rod + e.end; }

const Vec3& endPoint(const DiscreteRod& rod, int end) { return end == 0 ? rod.curve.points().front() : rod.curve.points().back(); }

// Joins the rod ends the design joins: all ends within the joint tolerance of each other, or the
// listed groups.
void joinEnds(const DiscreteStructure& s, const geometry::RodStructure& structure, EndSets& sets) {
  const geometry::MechanicsSpec& spec = structure.mechanics;
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
    return;
  }
  std::map<int, std::string> listed;
  for (std::size_t j = 0; j < spec.joints.size(); ++j)
    for (std::size_t k = 0; k < spec.joints[j].size(); ++k) {
      const ResolvedEnd e = s.resolve(spec.joints[j][k], structure);
      const std::string where = spec.joints[j][k].path;
      if (auto [it, fresh] = listed.emplace(endIndex(e), where); !fresh)
        s.fail(where, "this rod end is already in a joint (" + it->second + ")");
      sets.unite(endIndex(s.resolve(spec.joints[j][0], structure)), endIndex(e));
    }
}

}  // namespace

ResolvedEnd DiscreteStructure::resolve(const geometry::RodEndRef& ref, const geometry::RodStructure& structure) const {
  if (!ref.point) {
    for (std::size_t i = 0; i < structure.rods.size(); ++i)
      if (structure.rods[i].name() == ref.rod) return {static_cast<int>(i), ref.end == geometry::RodEnd::Start ? 0 : 1};
    fail(ref.path + ".rod", "no rod is named \"" + ref.rod + "\"");
  }
  ResolvedEnd best;
  double bestDistance = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < rods.size(); ++i)
    for (int end = 0; end < 2; ++end) {
      const double d = (endPoint(rods[i], end) - *ref.point).norm();
      if (d < bestDistance) bestDistance = d, best = {static_cast<int>(i), end};
    }
  if (bestDistance > structure.mechanics.jointTolerance)
    fail(ref.path + ".point", "no rod end lies within joint_tolerance (" + format(structure.mechanics.jointTolerance) +
                                  " mm) of " + format(*ref.point) + "; the nearest is the " + (best.end ? "end" : "start") +
                                  " of rod \"" + rods[best.rod].name + "\", " + format(bestDistance) +
                                  " mm away (loads and supports act on rod ends and joints)");
  return best;
}

void DiscreteStructure::keepSpec(const geometry::RodStructure& structure) {
  spec = structure.mechanics;
  auto byName = [&](geometry::RodEndRef& ref) {
    if (!ref.point) return;
    const ResolvedEnd e = resolve(ref, structure);
    ref.rod = rods[e.rod].name;
    ref.end = e.end == 0 ? geometry::RodEnd::Start : geometry::RodEnd::End;
    ref.point.reset();
  };
  for (auto& joint : spec.joints)
    for (auto& ref : joint) byName(ref);
  for (auto& support : spec.supports) byName(support.at);
  for (auto& load : spec.loads) byName(load.at);
}

void DiscreteStructure::buildNodes(const geometry::RodStructure& structure) {
  const geometry::MechanicsSpec& spec = structure.mechanics;
  const int endCount = static_cast<int>(2 * rods.size());
  EndSets sets(endCount);
  joinEnds(*this, structure, sets);
  std::map<int, std::size_t> nodeOf;
  for (int i = 0; i < endCount; ++i) {
    auto [it, fresh] = nodeOf.emplace(sets.find(i), nodes.size());
    if (fresh) nodes.emplace_back();
    nodes[it->second].ends.push_back({i / 2, i % 2});
  }
  for (const Node& node : nodes) joints += node.ends.size() > 1;
  auto nodeAt = [&](const geometry::RodEndRef& ref) -> Node& { return nodes[nodeOf.at(sets.find(endIndex(resolve(ref, structure))))]; };

  for (const auto& s : spec.supports) {
    Node& node = nodeAt(s.at);
    if (node.support) fail(s.at.path, "this rod end (or joint) already has a support (" + node.supportPath + ")");
    node.support = s.kind;
    node.supportPath = s.at.path;
    node.displacement = s.displacement;
    node.rotation = s.rotation;
    ++supports;
  }
  for (const auto& l : spec.loads) {
    Node& node = nodeAt(l.at);
    node.force += l.force;
    node.moment += l.moment;
  }
  if (supports == 0)
    fail("mechanics.supports", "no support: the structure could move as a rigid body; clamp or pin at least one rod end");

  // Every connected part of the structure needs a support of its own: joining each rod's two ends
  // in the same union-find turns the joints into connected parts.
  for (std::size_t r = 0; r < rods.size(); ++r) sets.unite(static_cast<int>(2 * r), static_cast<int>(2 * r + 1));
  std::vector<bool> held(endCount, false);
  for (const Node& node : nodes)
    if (node.support) held[sets.find(endIndex(node.ends.front()))] = true;
  for (std::size_t r = 0; r < rods.size(); ++r)
    if (!held[sets.find(static_cast<int>(2 * r))])
      fail("mechanics.supports", "rod \"" + rods[r].name + "\" belongs to a part of the structure without any support "
                                 "(it is not joined to a supported rod); support it or join it");

  for (Node& node : nodes) {
    const ResolvedEnd first = node.ends.front();
    const LocalState s0 = localState(rodOf(first), endBasis(first), reference);
    node.position0 = s0.r;
    node.quaternion0 = s0.q.normalized();
    const Eigen::Vector4d conj0(node.quaternion0[0], -node.quaternion0[1], -node.quaternion0[2], -node.quaternion0[3]);
    for (std::size_t i = 1; i < node.ends.size(); ++i) {
      const LocalState s = localState(rodOf(node.ends[i]), endBasis(node.ends[i]), reference);
      node.offsets0.push_back(s.r - s0.r);
      node.relative0.push_back(quaternionProduct<double>(conj0, s.q.normalized()));
    }
  }
}

}  // namespace rodfab::mechanics::detail
