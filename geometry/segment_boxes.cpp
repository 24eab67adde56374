#include "geometry/segment_boxes.hpp"

#include <algorithm>
#include <stdexcept>

namespace rodfab::geometry {

namespace {

// The levels above `boxes`: each box the union of kFanout consecutive boxes of the level below,
// until a level has at most kFanout boxes.
std::vector<std::vector<Eigen::AlignedBox3d>> hierarchy(std::vector<Eigen::AlignedBox3d> boxes) {
  std::vector<std::vector<Eigen::AlignedBox3d>> levels;
  if (boxes.empty()) return levels;
  constexpr std::size_t fanout = SegmentBoxes::kFanout;
  levels.push_back(std::move(boxes));
  while (levels.back().size() > fanout) {
    const std::vector<Eigen::AlignedBox3d>& below = levels.back();
    std::vector<Eigen::AlignedBox3d> level((below.size() + fanout - 1) / fanout);
    for (std::size_t n = 0; n < level.size(); ++n) {
      level[n].setEmpty();
      for (std::size_t c = fanout * n; c < std::min(fanout * n + fanout, below.size()); ++c) level[n].extend(below[c]);
    }
    levels.push_back(std::move(level));
  }
  return levels;
}

}  // namespace

SegmentBoxes::SegmentBoxes(std::vector<Eigen::AlignedBox3d> segmentBoxes, std::vector<Eigen::AlignedBox3d> hullBoxes) {
  if (!hullBoxes.empty() && hullBoxes.size() != segmentBoxes.size())
    throw std::invalid_argument("SegmentBoxes: one hull box per segment, or none");
  if (hullBoxes.empty()) hullBoxes = segmentBoxes;
  levels_ = hierarchy(std::move(segmentBoxes));
  hulls_ = hierarchy(std::move(hullBoxes));
  for (std::size_t l = 0, span = 1; l < levels_.size(); ++l, span *= kFanout) spans_.push_back(span);
}

}  // namespace rodfab::geometry
