// A box hierarchy over the segments of a polyline, in the polyline's order: which segments could
// reach a point, visited in increasing segment index, or nearest first with a distance cut-off (by a
// capsule per node holding the node's segments' own points).
// Rod::classify uses it to skip the sample segments of a rod that cannot reach the voxel it tests, and
// those that cannot hold a section deeper than one already found (geometry/README.md: why this layout
// and not Boost.Geometry's rtree).
#pragma once
#include "geometry/nurbs.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cstddef>
#include <limits>
#include <vector>

namespace rodfab::geometry {

class SegmentBoxes {
public:
  // Children per node: a node holds the union of kFanout consecutive boxes of the level below.
  static constexpr std::size_t kFanout = 4;

  // Every point within `radius` of the segment [a, b] (a ball when a == b).
  struct Capsule {
    Vec3 a = Vec3::Zero(), b = Vec3::Zero();
    double radius = 0.0;
  };

  SegmentBoxes() = default;
  // One reach box per segment (any box: the caller grows them by how far a segment reaches; empty
  // boxes are allowed and never contain a point), and one hull per segment holding the segment's own
  // points, for the nearest-first visit. Each node above gets a capsule holding the hulls of its
  // segments with a non-empty box (around the chord from its first segment's a to its last one's b,
  // or a ball, whichever is thinner), grown by `margin` for the rounding of the query's distances (the
  // caller's hulls include it already).
  SegmentBoxes(std::vector<Eigen::AlignedBox3d> segmentBoxes, const std::vector<Capsule>& hulls, double margin);

  std::size_t size() const { return levels_.empty() ? 0 : levels_.front().size(); }

  // Calls visit(i) for every segment i in [first, last) whose box contains p (boundary included), in
  // increasing i; a point with a NaN coordinate is in no box. Thread-safe (const, no state).
  template <class Visit>
  void forEachContaining(const Vec3& p, std::size_t first, std::size_t last, Visit&& visit) const {
    if (levels_.empty() || first >= last) return;
    const std::size_t top = levels_.size() - 1;
    for (std::size_t node = 0; node < levels_[top].size(); ++node) visitNode(p, top, node, first, last, visit);
  }

  // Calls visit(i) for the segments i in [first, last) whose reach box contains p and whose hull lies
  // within limit() of p (computed distance to its chord less its radius), nearest hull first: best
  // first over the whole hierarchy (a heap of nodes by their capsules' distance), so the first segment
  // visited is the nearest one, not the nearest within the first subtree entered. A node whose capsule
  // lies farther is skipped whole. limit() is asked again before every node is taken, so a visitor
  // that lowers it (a better candidate found) prunes what is left. Which segments are visited thus
  // depends on the limit's history; the order never on anything but p and the hulls. Thread-safe
  // (const, no state; the heap lives on the stack, and a node that does not fit is visited depth first
  // at once).
  template <class Limit, class Visit>
  void forEachNearestWithin(const Vec3& p, std::size_t first, std::size_t last, Limit&& limit, Visit&& visit) const {
    if (levels_.empty() || first >= last) return;
    NearHeap heap;
    auto offer = [&](std::size_t level, std::size_t node, double within) {
      const double d = reachingDistance(p, level, node, first, last);
      if (!(d <= within)) return;
      if (!heap.push({d, level, node})) visitNearest(p, level, node, node + 1, first, last, limit, visit);
    };
    const std::size_t top = levels_.size() - 1;
    for (std::size_t node = 0; node < levels_[top].size(); ++node) offer(top, node, limit());
    while (!heap.empty()) {
      const Near near = heap.pop();
      const double within = limit();
      if (!(near.distance <= within)) break;  // the rest are farther still
      if (near.level == 0) {
        visit(near.node);
        continue;
      }
      const std::size_t childEnd = std::min(kFanout * near.node + kFanout, levels_[near.level - 1].size());
      for (std::size_t child = kFanout * near.node; child < childEnd; ++child) offer(near.level - 1, child, within);
    }
  }

private:
  // A capsule as the query uses it: a, b - a, 1 / |b - a|^2 (0 for a ball), radius.
  struct Hull {
    Vec3 a, ab;
    double inverseSquaredLength, radius;

    // Distance from p to the chord, less the radius: no point of the capsule is nearer to p (up to
    // the rounding of a few ulps of |p - a| and |ab|, which the radius's margin covers).
    double lowerBound(const Vec3& p) const {
      const Vec3 ap = p - a;
      const double t = std::clamp(ap.dot(ab) * inverseSquaredLength, 0.0, 1.0);
      return (ap - t * ab).norm() - radius;
    }
  };

  // A node waiting in the best-first visit, and the heap of them (nearest on top).
  struct Near {
    double distance;
    std::size_t level, node;
  };
  class NearHeap {
  public:
    bool empty() const { return size_ == 0; }
    // False when full (the caller visits the node at once instead).
    bool push(const Near& n) {
      if (size_ == items_.size()) return false;
      items_[size_++] = n;
      std::push_heap(items_.begin(), items_.begin() + static_cast<std::ptrdiff_t>(size_), farther);
      return true;
    }
    Near pop() {
      std::pop_heap(items_.begin(), items_.begin() + static_cast<std::ptrdiff_t>(size_), farther);
      return items_[--size_];
    }

  private:
    static bool farther(const Near& x, const Near& y) {
      return x.distance > y.distance || (x.distance == y.distance && (x.level < y.level || (x.level == y.level && x.node > y.node)));
    }
    std::array<Near, 128> items_;
    std::size_t size_ = 0;
  };

  // The distance of node's capsule from p (NaN when p is outside its reach box or the node holds no
  // segment of [first, last)).
  double reachingDistance(const Vec3& p, std::size_t level, std::size_t node, std::size_t first, std::size_t last) const {
    const std::size_t span = spans_[level], begin = node * span;
    if (begin >= last || begin + span <= first || !levels_[level][node].contains(p)) return std::numeric_limits<double>::quiet_NaN();
    return hulls_[level][node].lowerBound(p);
  }

  template <class Visit>
  void visitNode(const Vec3& p, std::size_t level, std::size_t node, std::size_t first, std::size_t last, Visit& visit) const {
    // The segments under `node` are [node * kFanout^level, (node + 1) * kFanout^level).
    const std::size_t span = spans_[level], begin = node * span;
    if (begin >= last || begin + span <= first || !levels_[level][node].contains(p)) return;
    if (level == 0) {
      visit(node);
      return;
    }
    const std::size_t childEnd = std::min(kFanout * node + kFanout, levels_[level - 1].size());
    for (std::size_t child = kFanout * node; child < childEnd; ++child) visitNode(p, level - 1, child, first, last, visit);
  }

  // Nodes [nodeBegin, nodeEnd) of `level` (at most kFanout), depth first, nearest sibling first: the
  // best-first visit's fallback when its heap is full.
  template <class Limit, class Visit>
  void visitNearest(const Vec3& p, std::size_t level, std::size_t nodeBegin, std::size_t nodeEnd, std::size_t first,
                    std::size_t last, Limit& limit, Visit& visit) const {
    std::array<Near, kFanout> near;
    std::size_t count = 0;
    const double within = limit();
    for (std::size_t node = nodeBegin; node < nodeEnd; ++node) {
      const double d = reachingDistance(p, level, node, first, last);
      if (!(d <= within)) continue;
      // Insertion by distance; equal distances keep the index order.
      std::size_t at = count++;
      for (; at > 0 && near[at - 1].distance > d; --at) near[at] = near[at - 1];
      near[at] = {d, level, node};
    }
    for (std::size_t n = 0; n < count; ++n) {
      if (!(near[n].distance <= limit())) break;  // the rest are farther still
      const std::size_t node = near[n].node;
      if (level == 0) visit(node);
      else visitNearest(p, level - 1, kFanout * node, std::min(kFanout * node + kFanout, levels_[level - 1].size()), first, last,
                        limit, visit);
    }
  }

  // levels_[0]: the segments' boxes; levels_[l][n]: the union of levels_[l - 1][kFanout n ...]; the
  // last level has at most kFanout boxes. hulls_[l][n]: a capsule holding the hulls of the segments
  // under levels_[l][n].
  std::vector<std::vector<Eigen::AlignedBox3d>> levels_;
  std::vector<std::vector<Hull>> hulls_;
  std::vector<std::size_t> spans_;  // segments under one node of each level: kFanout^level
};

}  // namespace rodfab::geometry
