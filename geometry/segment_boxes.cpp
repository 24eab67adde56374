#include "geometry/segment_boxes.hpp"
#include "geometry/segment.hpp"

#include <algorithm>
#include <cmath>
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

// The radius around [a, b] that holds every capsule of hulls[first, last) whose segment can be
// visited (the distance to a segment is convex: a capsule's chord is as near as its farther end).
double radiusHolding(const Vec3& a, const Vec3& b, const std::vector<SegmentBoxes::Capsule>& hulls,
                     const std::vector<Eigen::AlignedBox3d>& boxes, std::size_t first, std::size_t last) {
  double radius = 0.0;
  for (std::size_t i = first; i < last; ++i) {
    if (boxes[i].isEmpty()) continue;
    const double far = std::max(distanceToSegment(hulls[i].a, a, b), distanceToSegment(hulls[i].b, a, b));
    radius = std::max(radius, far + hulls[i].radius);
  }
  return radius;
}

// A capsule holding the visitable hulls of segments [first, last): around their chord, or a ball
// around the centre of their ends' box, whichever is thinner.
SegmentBoxes::Capsule enclosing(const std::vector<SegmentBoxes::Capsule>& hulls, const std::vector<Eigen::AlignedBox3d>& boxes,
                                std::size_t first, std::size_t last) {
  Eigen::AlignedBox3d ends;
  ends.setEmpty();
  for (std::size_t i = first; i < last; ++i) {
    if (boxes[i].isEmpty()) continue;
    ends.extend(hulls[i].a);
    ends.extend(hulls[i].b);
  }
  if (ends.isEmpty()) return {};
  SegmentBoxes::Capsule chord{hulls[first].a, hulls[last - 1].b, 0.0};
  chord.radius = radiusHolding(chord.a, chord.b, hulls, boxes, first, last);
  const Vec3 centre = ends.center();
  const double ball = radiusHolding(centre, centre, hulls, boxes, first, last);
  return ball < chord.radius ? SegmentBoxes::Capsule{centre, centre, ball} : chord;
}

}  // namespace

SegmentBoxes::SegmentBoxes(std::vector<Eigen::AlignedBox3d> segmentBoxes, const std::vector<Capsule>& hulls, double margin) {
  if (hulls.size() != segmentBoxes.size()) throw std::invalid_argument("SegmentBoxes: one hull per segment");
  levels_ = hierarchy(std::move(segmentBoxes));
  for (std::size_t l = 0, span = 1; l < levels_.size(); ++l, span *= kFanout) {
    spans_.push_back(span);
    std::vector<Hull>& level = hulls_.emplace_back(levels_[l].size());
    for (std::size_t n = 0; n < level.size(); ++n) {
      const std::size_t first = n * span, last = std::min(first + span, hulls.size());
      Capsule c = l == 0 ? hulls[n] : enclosing(hulls, levels_.front(), first, last);
      if (l > 0) c.radius += margin;
      const Vec3 ab = c.b - c.a;
      const double length2 = ab.squaredNorm();
      // A chord too short for its inverse square is taken at its end a (farther by at most its length).
      const double inverse = length2 > 0.0 ? 1.0 / length2 : 0.0;
      level[n] = {c.a, ab, std::isfinite(inverse) ? inverse : 0.0, c.radius + (std::isfinite(inverse) ? 0.0 : std::sqrt(length2))};
    }
  }
}

}  // namespace rodfab::geometry
