#include "materials/dither_quality.hpp"

#include "common/interrupt.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::materials {

namespace {

std::string coordText(const openvdb::Coord& c) {
  return "(" + std::to_string(c.x()) + ", " + std::to_string(c.y()) + ", " + std::to_string(c.z()) + ")";
}

// The region's bounding box as dense arrays, x fastest.
struct DenseRegion {
  std::array<std::size_t, 3> dim{0, 0, 0};
  std::vector<std::uint8_t> inside, vero;
  std::vector<float> target;
  std::size_t voxels = 0;

  std::size_t cells() const { return dim[0] * dim[1] * dim[2]; }
  std::array<std::size_t, 3> stride() const { return {1, dim[0], dim[0] * dim[1]}; }
};

DenseRegion densify(const openvdb::FloatGrid& fraction, const openvdb::BoolGrid& material) {
  DenseRegion region;
  const openvdb::CoordBBox box = fraction.evalActiveVoxelBoundingBox();
  if (box.empty()) {
    if (material.activeVoxelCount() != 0)
      throw std::invalid_argument("dither quality: the fraction grid is empty but the material grid is not");
    return region;
  }
  const openvdb::Coord d = box.dim();
  for (int a = 0; a < 3; ++a) region.dim[a] = static_cast<std::size_t>(d[a]);
  if (region.cells() > (std::size_t{1} << 30))
    throw std::invalid_argument("dither quality: the region's bounding box has " + std::to_string(region.cells()) +
                                " cells, expected at most 2^30 (measure a smaller piece)");
  region.inside.assign(region.cells(), 0);
  region.vero.assign(region.cells(), 0);
  region.target.assign(region.cells(), 0.0f);
  const auto s = region.stride();
  openvdb::BoolGrid::ConstAccessor materialAt = material.getConstAccessor();
  for (auto it = fraction.cbeginValueOn(); it; ++it) {
    const openvdb::CoordBBox part = it.getBoundingBox();  // one voxel, or an active tile
    for (auto ijk = part.begin(); ijk; ++ijk) {
      bool vero = false;
      if (!materialAt.probeValue(*ijk, vero))
        throw std::invalid_argument("dither quality: voxel " + coordText(*ijk) +
                                    " is in the fraction grid's region but not active in the material grid");
      const openvdb::Coord p = *ijk - box.min();
      const std::size_t c = p.x() * s[0] + p.y() * s[1] + p.z() * s[2];
      region.inside[c] = 1;
      region.vero[c] = vero ? 1 : 0;
      region.target[c] = *it;
      ++region.voxels;
    }
  }
  if (material.activeVoxelCount() != region.voxels)
    throw std::invalid_argument("dither quality: the material grid has " + std::to_string(material.activeVoxelCount()) +
                                " active voxels, the fraction grid " + std::to_string(region.voxels) +
                                ": expected the same region");
  return region;
}

// Convolves every line along `axis` with `kernel` (centre at kernel.size() / 2); zero outside the box.
std::vector<double> convolveAxis(const std::vector<double>& in, const DenseRegion& region, int axis,
                                 const std::vector<double>& kernel) {
  std::vector<double> out(in.size(), 0.0);
  const auto s = region.stride();
  const std::size_t n = region.dim[axis], step = s[axis];
  const int other1 = (axis + 1) % 3, other2 = (axis + 2) % 3;
  const std::size_t lines = region.dim[other1] * region.dim[other2];
  const auto radius = static_cast<std::ptrdiff_t>(kernel.size() / 2);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, lines), [&](const tbb::blocked_range<std::size_t>& r) {
    common::throwIfInterrupted();  // a 192^3 region's convolutions take tens of seconds
    for (std::size_t line = r.begin(); line != r.end(); ++line) {
      const std::size_t base = (line % region.dim[other1]) * s[other1] + (line / region.dim[other1]) * s[other2];
      for (std::ptrdiff_t x = 0; x < static_cast<std::ptrdiff_t>(n); ++x) {
        double sum = 0.0;
        const std::ptrdiff_t lo = std::max<std::ptrdiff_t>(0, x - radius);
        const std::ptrdiff_t hi = std::min<std::ptrdiff_t>(static_cast<std::ptrdiff_t>(n) - 1, x + radius);
        for (std::ptrdiff_t y = lo; y <= hi; ++y) sum += kernel[y - x + radius] * in[base + y * step];
        out[base + x * step] = sum;
      }
    }
  });
  return out;
}

double lowPassRms(const DenseRegion& region, const openvdb::Vec3d& voxelSizeMm, double sigmaMm) {
  if (!(sigmaMm > 0)) throw std::invalid_argument("low-pass error: sigma must be > 0 mm");
  if (region.voxels == 0) return 0.0;
  std::vector<double> error(region.cells(), 0.0), weight(region.cells(), 0.0);
  for (std::size_t c = 0; c < region.cells(); ++c) {
    if (!region.inside[c]) continue;
    error[c] = (region.vero[c] ? 1.0 : 0.0) - region.target[c];
    weight[c] = 1.0;
  }
  for (int axis = 0; axis < 3; ++axis) {
    const double sigma = sigmaMm / voxelSizeMm[axis];
    const int radius = static_cast<int>(std::ceil(4.0 * sigma));
    std::vector<double> kernel(2 * radius + 1);
    for (int d = -radius; d <= radius; ++d) kernel[d + radius] = std::exp(-0.5 * d * d / (sigma * sigma));
    error = convolveAxis(error, region, axis, kernel);
    weight = convolveAxis(weight, region, axis, kernel);
  }
  double sum = 0.0;
  for (std::size_t c = 0; c < region.cells(); ++c)
    if (region.inside[c]) sum += (error[c] / weight[c]) * (error[c] / weight[c]);
  return std::sqrt(sum / static_cast<double>(region.voxels));
}

std::size_t largestVeroCluster(const DenseRegion& region) {
  const auto s = region.stride();
  std::vector<std::uint8_t> seen(region.cells(), 0);
  std::vector<std::size_t> stack;
  std::size_t largest = 0;
  for (std::size_t start = 0; start < region.cells(); ++start) {
    if (!region.vero[start] || seen[start]) continue;
    std::size_t size = 0;
    seen[start] = 1;
    stack.push_back(start);
    while (!stack.empty()) {
      const std::size_t c = stack.back();
      stack.pop_back();
      ++size;
      const std::array<std::size_t, 3> p{c % region.dim[0], (c / s[1]) % region.dim[1], c / s[2]};
      for (int a = 0; a < 3; ++a) {
        if (p[a] > 0 && region.vero[c - s[a]] && !seen[c - s[a]]) {
          seen[c - s[a]] = 1;
          stack.push_back(c - s[a]);
        }
        if (p[a] + 1 < region.dim[a] && region.vero[c + s[a]] && !seen[c + s[a]]) {
          seen[c + s[a]] = 1;
          stack.push_back(c + s[a]);
        }
      }
    }
    largest = std::max(largest, size);
  }
  return largest;
}

double meanRunLength(const DenseRegion& region, int axis) {
  const auto s = region.stride();
  const int other1 = (axis + 1) % 3, other2 = (axis + 2) % 3;
  std::size_t runs = 0;
  for (std::size_t b = 0; b < region.dim[other2]; ++b)
    for (std::size_t a = 0; a < region.dim[other1]; ++a) {
      const std::size_t base = a * s[other1] + b * s[other2];
      bool previousInside = false;
      std::uint8_t previous = 0;
      for (std::size_t x = 0; x < region.dim[axis]; ++x) {
        const std::size_t c = base + x * s[axis];
        if (region.inside[c] && (!previousInside || region.vero[c] != previous)) ++runs;
        previousInside = region.inside[c];
        previous = region.vero[c];
      }
    }
  return runs ? static_cast<double>(region.voxels) / static_cast<double>(runs) : 0.0;
}

}  // namespace

double lowPassErrorRms(const openvdb::FloatGrid& fraction, const openvdb::BoolGrid& material, double sigmaMm) {
  return lowPassRms(densify(fraction, material), fraction.voxelSize(), sigmaMm);
}

DitherQuality measureDitherQuality(const openvdb::FloatGrid& fraction, const openvdb::BoolGrid& material) {
  const DenseRegion region = densify(fraction, material);
  DitherQuality q;
  q.voxels = region.voxels;
  if (region.voxels == 0) return q;
  double target = 0.0;
  for (std::size_t c = 0; c < region.cells(); ++c) {
    if (!region.inside[c]) continue;
    target += region.target[c];
    q.veroVoxels += region.vero[c];
  }
  const auto n = static_cast<double>(region.voxels);
  q.targetMean = target / n;
  q.achievedMean = static_cast<double>(q.veroVoxels) / n;
  q.meanBias = q.achievedMean - q.targetMean;
  q.lowPassRms100um = lowPassRms(region, fraction.voxelSize(), 0.100);
  q.lowPassRms250um = lowPassRms(region, fraction.voxelSize(), 0.250);
  q.largestVeroClusterShare =
      q.veroVoxels ? static_cast<double>(largestVeroCluster(region)) / static_cast<double>(q.veroVoxels) : 0.0;
  for (int a = 0; a < 3; ++a) q.meanRunLength[a] = meanRunLength(region, a);
  return q;
}

}  // namespace rodfab::materials
