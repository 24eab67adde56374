// A box hierarchy over the segments of a polyline, in the polyline's order: which segments could
// reach a point, visited in increasing segment index, or nearest first with a distance cut-off.
// Rod::classify uses it to skip the sample segments of a rod that cannot reach the voxel it tests, and
// those that cannot hold a section deeper than one already found (geometry/README.md: why this layout
// and not Boost.Geometry's rtree).
#pragma once
#include "geometry/nurbs.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cstddef>
#include <vector>

namespace rodfab::geometry {

class SegmentBoxes {
public:
  // Children per node: a node holds the union of kFanout consecutive boxes of the level below.
  static constexpr std::size_t kFanout = 4;

  SegmentBoxes() = default;
  // One reach box per segment (any box: the caller grows them by how far a segment reaches), and
  // optionally one hull box per segment (a box holding the segment's own points, for the nearest-first
  // visit; the reach boxes serve when none are given). Empty boxes are allowed and never contain a point.
  explicit SegmentBoxes(std::vector<Eigen::AlignedBox3d> segmentBoxes, std::vector<Eigen::AlignedBox3d> hullBoxes = {});

  std::size_t size() const { return levels_.empty() ? 0 : levels_.front().size(); }

  // Calls visit(i) for every segment i in [first, last) whose box contains p (boundary included), in
  // increasing i; a point with a NaN coordinate is in no box. Thread-safe (const, no state).
  template <class Visit>
  void forEachContaining(const Vec3& p, std::size_t first, std::size_t last, Visit&& visit) const {
    if (levels_.empty() || first >= last) return;
    const std::size_t top = levels_.size() - 1;
    for (std::size_t node = 0; node < levels_[top].size(); ++node) visitNode(p, top, node, first, last, visit);
  }

  // Calls visit(i) for the segments i in [first, last) whose reach box contains p and whose hull box
  // lies within sqrt(squaredLimit()) of p, nearest hull first (among siblings of the hierarchy: a
  // best-first descent, not a global sort; equal distances in increasing i). squaredLimit() is asked
  // again before every descent, so a visitor that lowers it (a better candidate found) prunes what is
  // left. Which segments are visited thus depends on the limit's history; the order never on anything
  // but p and the boxes. Thread-safe (const, no state).
  template <class Limit, class Visit>
  void forEachNearestWithin(const Vec3& p, std::size_t first, std::size_t last, Limit&& squaredLimit, Visit&& visit) const {
    if (levels_.empty() || first >= last) return;
    const std::size_t top = levels_.size() - 1;
    visitNearest(p, top, 0, levels_[top].size(), first, last, squaredLimit, visit);
  }

private:
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

  // Nodes [nodeBegin, nodeEnd) of `level` (at most kFanout: the top level, or one node's children).
  template <class Limit, class Visit>
  void visitNearest(const Vec3& p, std::size_t level, std::size_t nodeBegin, std::size_t nodeEnd, std::size_t first,
                    std::size_t last, Limit& squaredLimit, Visit& visit) const {
    struct Near {
      double squaredDistance;
      std::size_t node;
    };
    std::array<Near, kFanout> near;
    std::size_t count = 0;
    const double limit = squaredLimit();
    for (std::size_t node = nodeBegin; node < nodeEnd; ++node) {
      const std::size_t span = spans_[level], begin = node * span;
      if (begin >= last || begin + span <= first || !levels_[level][node].contains(p)) continue;
      const double d = hulls_[level][node].squaredExteriorDistance(p);
      if (!(d <= limit)) continue;
      // Insertion by distance; equal distances keep the index order.
      std::size_t at = count++;
      for (; at > 0 && near[at - 1].squaredDistance > d; --at) near[at] = near[at - 1];
      near[at] = {d, node};
    }
    for (std::size_t n = 0; n < count; ++n) {
      if (!(near[n].squaredDistance <= squaredLimit())) break;  // the rest are farther still
      const std::size_t node = near[n].node;
      if (level == 0) visit(node);
      else visitNearest(p, level - 1, kFanout * node, std::min(kFanout * node + kFanout, levels_[level - 1].size()), first, last,
                        squaredLimit, visit);
    }
  }

  // levels_[0]: the segments' boxes; levels_[l][n]: the union of levels_[l - 1][kFanout n ...]; the
  // last level has at most kFanout boxes. hulls_: the same hierarchy over the hull boxes.
  std::vector<std::vector<Eigen::AlignedBox3d>> levels_, hulls_;
  std::vector<std::size_t> spans_;  // segments under one node of each level: kFanout^level
};

}  // namespace rodfab::geometry
