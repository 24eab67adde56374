// A box hierarchy over the segments of a polyline, in the polyline's order: which segments could
// reach a point, visited in increasing segment index. Rod::classify uses it to skip the sample
// segments of a rod that cannot reach the voxel it tests (geometry/README.md: why this layout and not
// Boost.Geometry's rtree).
#pragma once
#include "geometry/nurbs.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cstddef>
#include <vector>

namespace rodfab::geometry {

class SegmentBoxes {
public:
  // Children per node: a node holds the union of kFanout consecutive boxes of the level below.
  static constexpr std::size_t kFanout = 4;

  SegmentBoxes() = default;
  // One box per segment (any box: the caller grows them by how far a segment reaches). Empty boxes
  // are allowed and never contain a point.
  explicit SegmentBoxes(std::vector<Eigen::AlignedBox3d> segmentBoxes);

  std::size_t size() const { return levels_.empty() ? 0 : levels_.front().size(); }

  // Calls visit(i) for every segment i in [first, last) whose box contains p (boundary included), in
  // increasing i; a point with a NaN coordinate is in no box. Thread-safe (const, no state).
  template <class Visit>
  void forEachContaining(const Vec3& p, std::size_t first, std::size_t last, Visit&& visit) const {
    if (levels_.empty() || first >= last) return;
    const std::size_t top = levels_.size() - 1;
    for (std::size_t node = 0; node < levels_[top].size(); ++node) visitNode(p, top, node, first, last, visit);
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

  // levels_[0]: the segments' boxes; levels_[l][n]: the union of levels_[l - 1][kFanout n ...]; the
  // last level has at most kFanout boxes.
  std::vector<std::vector<Eigen::AlignedBox3d>> levels_;
  std::vector<std::size_t> spans_;  // segments under one node of each level: kFanout^level
};

}  // namespace rodfab::geometry
