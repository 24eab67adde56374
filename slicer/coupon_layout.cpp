#include "slicer/coupon_layout.hpp"

#include "printer_profiles/job_layout.hpp"
#include "printer_profiles/job_writer.hpp"
#include "materials/fraction_map.hpp"
#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "voxel/printer_grid.hpp"

#include <boost/algorithm/string/join.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

namespace rodfab::slicer {

namespace {

// `v` as printf's `format` for one double prints it ("%.3f": millimetres in messages).
std::string printed(const char* format, double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string mm(double v) { return printed("%.3f", v); }
std::string number(double v) { return printed("%.10g", v); }

constexpr const char* kAxis[3] = {"x", "y", "z"};

openvdb::CoordBBox rowOf(const openvdb::Coord& bar, int gapI, int count) {
  return {openvdb::Coord(0, 0, 0), openvdb::Coord(count * bar.x() + (count - 1) * gapI - 1, 0, 0)};
}

nlohmann::json coord(const openvdb::Coord& c) { return {c.x(), c.y(), c.z()}; }

}  // namespace

std::string barSizeText(const CouponLayout& layout, const std::array<double, 3>& voxelMm) {
  return mm(layout.bar.x() * voxelMm[0]) + " x " + mm(layout.bar.y() * voxelMm[1]) + " x " + mm(layout.bar.z() * voxelMm[2]) + " mm";
}

int CouponLayout::barAt(int i, int j) const {
  if (i < 0 || j < 0) return -1;
  const int pitchI = bar.x() + gapI, pitchJ = bar.y() + gapJ;
  const int column = i / pitchI, rowFromBottom = j / pitchJ;
  if (i % pitchI >= bar.x() || j % pitchJ >= bar.y() || column >= perRow || rowFromBottom >= rows) return -1;
  const std::size_t n = static_cast<std::size_t>((rows - 1 - rowFromBottom) * perRow + column);
  return n < bars.size() ? static_cast<int>(n) : -1;
}

CouponVoxels couponVoxels(const printer_profiles::Profile& profile, const std::array<double, 3>& sizeMm, double gapMm) {
  const std::array<double, 3>& voxel = profile.voxelSizeMm;
  std::array<double, 3> bar{};
  std::vector<std::string> tooLarge;
  for (int a = 0; a < 3; ++a) {
    bar[a] = std::round(sizeMm[a] / voxel[a]);
    if (bar[a] < 1.0)
      throw std::invalid_argument("--size: " + number(sizeMm[a]) + " mm along " + kAxis[a] + " is less than one voxel (" +
                                  number(voxel[a]) + " mm)");
    if (bar[a] * voxel[a] > profile.trayMm[a] + 1e-9)
      tooLarge.push_back("by " + mm(bar[a] * voxel[a] - profile.trayMm[a]) + " mm along " + kAxis[a]);
  }
  if (!tooLarge.empty())
    throw std::runtime_error("a bar of " + mm(bar[0] * voxel[0]) + " x " + mm(bar[1] * voxel[1]) + " x " + mm(bar[2] * voxel[2]) +
                             " mm does not fit the " + profile.printer + " tray (" + mm(profile.trayMm[0]) + " x " +
                             mm(profile.trayMm[1]) + " x " + mm(profile.trayMm[2]) + " mm): too large " +
                             boost::algorithm::join(tooLarge, ", "));
  CouponVoxels out;
  out.bar = openvdb::Coord(static_cast<int>(bar[0]), static_cast<int>(bar[1]), static_cast<int>(bar[2]));
  out.gapI = static_cast<int>(std::round(gapMm / voxel[0]));
  out.gapJ = static_cast<int>(std::round(gapMm / voxel[1]));
  if (out.gapI < 1 || out.gapJ < 1)
    throw std::invalid_argument("--gap: " + number(gapMm) + " mm is less than one voxel along " + (out.gapI < 1 ? "x" : "y") +
                                " (" + number(voxel[out.gapI < 1 ? 0 : 1]) + " mm): the bars would touch");
  return out;
}

CouponLayout planCouponLayout(const printer_profiles::Profile& profile, std::size_t count, const CouponVoxels& sizes) {
  CouponLayout l;
  l.bar = sizes.bar;
  l.gapI = sizes.gapI;
  l.gapJ = sizes.gapJ;
  const openvdb::Coord& bar = sizes.bar;
  int maxPerRow = static_cast<int>(count);
  for (; maxPerRow > 1; --maxPerRow) {
    try {
      printer_profiles::planJob(profile, rowOf(bar, l.gapI, maxPerRow));
      break;
    } catch (const printer_profiles::TrayFitError&) {
    }
  }
  l.rows = static_cast<int>((count + maxPerRow - 1) / maxPerRow);
  l.perRow = static_cast<int>((count + l.rows - 1) / l.rows);  // balanced rows
  for (std::size_t n = 0; n < count; ++n) {
    const int row = static_cast<int>(n) / l.perRow, column = static_cast<int>(n) % l.perRow;
    const openvdb::Coord min(column * (bar.x() + l.gapI), (l.rows - 1 - row) * (bar.y() + l.gapJ), 0);
    l.bars.emplace_back(min, min + bar - openvdb::Coord(1));
  }
  l.bounds = {openvdb::Coord(0), openvdb::Coord(l.perRow * bar.x() + (l.perRow - 1) * l.gapI - 1,
                                                l.rows * bar.y() + (l.rows - 1) * l.gapJ - 1, bar.z() - 1)};
  return l;
}

std::uint64_t couponJobBytes(const CouponLayout& layout, const printer_profiles::Profile& profile, int contactSheetLayers,
                             int bandLayers, const materials::Ditherer& ditherer) {
  // Per voxel of a band's leaves (whole 8-layer slabs, whatever the band's layers): the fractions (float
  // leaves: the node, its 2 KiB buffer, glibc's header on each) of both bands in flight (the source makes
  // one while the other is dithered), and the material (bool leaves) of those bands and of the trees the
  // ditherer's recycler keeps. Counted from the types: 5 bytes a voxel before, which left the estimate
  // under the peak (three 400 x 40 x 1.5 mm bars: 1.2 GB against 1.30 GB resident).
  using FloatLeaf = openvdb::FloatTree::LeafNodeType;
  using BoolLeaf = openvdb::BoolTree::LeafNodeType;
  const double floatLeafBytes = double(sizeof(FloatLeaf)) + double(FloatLeaf::SIZE * sizeof(float)) + 2.0 * 16.0;
  const double boolLeafBytes = double(sizeof(BoolLeaf)) + 16.0;
  const int heldLayers = (bandLayers + kLeafLayers - 1) / kLeafLayers * kLeafLayers;
  const int fractionLayers = heldLayers + (ditherer.readsNextLayer() ? kLeafLayers : 0);  // the next layer's slab
  const double layerBytes = (kBandsInFlight * floatLeafBytes * fractionLayers +
                             (kBandsInFlight + double(ditherer.keptTrees())) * boolLeafBytes * heldLayers) / double(FloatLeaf::SIZE);
  const openvdb::Coord d = layout.bounds.dim();
  const double bands = layerBytes * double(d.x()) * double(d.y());
  // The ditherer's own buffers (error diffusion's layer slots): every bar is solid, so a layer holds
  // their footprints; a band's leaves are their leaf columns over the slabs it spans.
  materials::DitherBand band{0.0, 0.0, bandLayers};
  for (const openvdb::CoordBBox& bar : layout.bars) {
    const openvdb::Coord b = bar.dim();
    band.layerVoxels += double(b.x()) * double(b.y());
    band.leaves += std::ceil(b.x() / double(kLeafLayers) + 1.0) * std::ceil(b.y() / double(kLeafLayers) + 1.0) *
                   (heldLayers / kLeafLayers + 1.0);
  }
  const double dither = ditherer.workingBytes(band, stageConcurrency());
  return common::saturatedBytes(double(jobWriterBytes(profile, layout.bounds, contactSheetLayers)) + bands + dither);
}

BandSource couponBands(const CouponLayout& layout, const std::vector<double>& fractions,
                       const printer_profiles::Profile& profile, const openvdb::Vec3d& originMm) {
  return [&layout, &fractions, transform = voxel::printerTransform(profile.voxelSize(), originMm)](int k0, int k1, bool withNextLayer) {
    common::throwIfInterrupted();
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.0f);
    grid->setName(materials::kFractionGridName);
    grid->setTransform(transform->copy());
    const int top = k1 - 1 + (withNextLayer ? 1 : 0);
    for (std::size_t n = 0; n < layout.bars.size(); ++n) {
      common::throwIfInterrupted();  // a band of a long bar takes a second
      openvdb::CoordBBox box = layout.bars[n];
      box.min().z() = std::max(box.min().z(), k0);
      box.max().z() = std::min(box.max().z(), top);
      if (!box.empty()) grid->tree().denseFill(box, static_cast<float>(fractions[n]), true);  // leaf voxels, no tiles
    }
    return BandGrids{grid, nullptr};
  };
}

BarCountingDitherer::BarCountingDitherer(materials::Ditherer& inner, const CouponLayout& layout)
    : inner_(inner), layout_(layout), vero_(layout.bars.size(), 0), voxels_(layout.bars.size(), 0) {}

void BarCountingDitherer::reset() {
  inner_.reset();
  std::fill(vero_.begin(), vero_.end(), 0);
  std::fill(voxels_.begin(), voxels_.end(), 0);
}

openvdb::BoolGrid::Ptr BarCountingDitherer::ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) {
  openvdb::BoolGrid::Ptr material = inner_.ditherLayers(fraction, k0, k1);
  for (auto leaf = material->tree().cbeginLeaf(); leaf; ++leaf) countLeaf(*leaf);
  return material;
}

void BarCountingDitherer::countLeaf(const openvdb::BoolTree::LeafNodeType& leaf) {
  const openvdb::CoordBBox box = leaf.getNodeBoundingBox();
  const int bar = layout_.barAt(box.min().x(), box.min().y());
  if (bar >= 0 && bar == layout_.barAt(box.max().x(), box.max().y())) {
    // The whole leaf column lies in one bar: count its bits a word at a time.
    const auto& mask = leaf.getValueMask();
    const auto* values = leaf.buffer().data();
    for (openvdb::Index w = 0; w < mask.WORD_COUNT; ++w) {
      const openvdb::Index64 on = mask.getWord<openvdb::Index64>(w);
      voxels_[static_cast<std::size_t>(bar)] += static_cast<std::uint64_t>(std::popcount(on));
      vero_[static_cast<std::size_t>(bar)] += static_cast<std::uint64_t>(std::popcount(on & values[w]));
    }
    return;
  }
  for (auto v = leaf.cbeginValueOn(); v; ++v) {
    const int b = layout_.barAt(v.getCoord().x(), v.getCoord().y());
    if (b < 0) throw std::logic_error("coupons: a voxel outside every bar was dithered");
    ++voxels_[static_cast<std::size_t>(b)];
    vero_[static_cast<std::size_t>(b)] += *v ? 1 : 0;
  }
}

nlohmann::json couponBarsJson(const CouponLayout& layout, const std::vector<double>& fractions,
                              const BarCountingDitherer& counted, std::uint64_t seed, const std::array<double, 3>& voxelMm) {
  const auto cornerMm = [&](const openvdb::Coord& c) { return nlohmann::json{c.x() * voxelMm[0], c.y() * voxelMm[1], c.z() * voxelMm[2]}; };
  const std::array<double, 3> barMm = {layout.bar.x() * voxelMm[0], layout.bar.y() * voxelMm[1], layout.bar.z() * voxelMm[2]};
  nlohmann::json bars = nlohmann::json::array();
  for (std::size_t n = 0; n < layout.bars.size(); ++n) {
    const openvdb::CoordBBox& b = layout.bars[n];
    const std::uint64_t all = counted.voxels()[n], vero = counted.vero()[n];
    if (all != static_cast<std::uint64_t>(b.volume()))
      throw std::logic_error("coupons: bar " + std::to_string(n) + " was dithered with " + std::to_string(all) +
                             " voxels, expected " + std::to_string(b.volume()));
    char specimen[32];
    std::snprintf(specimen, sizeof specimen, "coupon-%02zu", n);
    bars.push_back({{"index", n},
                    {"specimen", specimen},
                    {"vero_fraction", fractions[n]},
                    {"ditherer", std::string(counted.name())},
                    {"seed", seed},
                    {"row", static_cast<int>(n) / layout.perRow},
                    {"column", static_cast<int>(n) % layout.perRow},
                    {"position_mm", cornerMm(b.min())},
                    {"bounds_mm", {{"min", cornerMm(b.min())}, {"max", cornerMm(b.max() + openvdb::Coord(1))}}},
                    {"bounds_voxels", {{"min", coord(b.min())}, {"max", coord(b.max())}}},
                    {"size_mm", barMm},
                    {"voxels", all},
                    {"vero_voxels", vero},
                    {"vero_share", all ? static_cast<double>(vero) / static_cast<double>(all) : 0.0}});
  }
  return bars;
}

}  // namespace rodfab::slicer
