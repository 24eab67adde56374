#include "geometry/segment_boxes.hpp"

#include <algorithm>

namespace rodfab::geometry {

SegmentBoxes::SegmentBoxes(std::vector<Eigen::AlignedBox3d> segmentBoxes) {
  if (segmentBoxes.empty()) return;
  levels_.push_back(std::move(segmentBoxes));
  spans_.push_back(1);
  while (levels_.back().size() > kFanout) {
    const std::vector<Eigen::AlignedBox3d>& below = levels_.back();
    std::vector<Eigen::AlignedBox3d> level((below.size() + kFanout - 1) / kFanout);
    for (std::size_t n = 0; n < level.size(); ++n) {
      level[n].setEmpty();
      for (std::size_t c = kFanout * n; c < std::min(kFanout * n + kFanout, below.size()); ++c) level[n].extend(below[c]);
    }
    spans_.push_back(spans_.back() * kFanout);
    levels_.push_back(std::move(level));
  }
}

}  // namespace rodfab::geometry
