// The coupons of `rodfab coupons`: DMA calibration bars, one uniform bar per Vero fraction, laid out
// on the tray; the bands of their fractions for the job pipeline, the Vero each bar received, the
// memory a coupon job needs, and the manifest's record of the bars.
#pragma once

#include "materials/ditherer.hpp"
#include "printer_profiles/profile.hpp"
#include "slicer/job_pipeline.hpp"

#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace rodfab::slicer {

// Where the bars lie: rows along x, wrapping into further rows along y, bar 0 top-left as the layer
// images show it (row 0 of the tray = the largest y). Every bar is a box of voxels from layer 0.
struct CouponLayout {
  openvdb::Coord bar;         // voxels per bar along x, y, z
  int gapI = 0, gapJ = 0;     // voxels between bars along x and y
  int perRow = 0, rows = 0;
  std::vector<openvdb::CoordBBox> bars;
  openvdb::CoordBBox bounds;  // all bars

  // The bar holding column (i, j) of the layout, or -1 (a gap or outside).
  int barAt(int i, int j) const;
};

// "30.014 x 5.080 x 1.500 mm": a bar of `layout` in whole voxels of `voxelMm`, for messages.
std::string barSizeText(const CouponLayout& layout, const std::array<double, 3>& voxelMm);

// A bar of `sizeMm` and gaps of `gapMm` (x and y) in whole voxels of `profile`, the nearest to what was
// asked. Throws std::invalid_argument naming --size or --gap for less than one voxel (a usage error),
// and std::runtime_error saying by how much for a bar larger than the tray (checked before the sizes
// become voxel indices, so a bar many times the tray cannot overflow them).
struct CouponVoxels {
  openvdb::Coord bar;
  int gapI = 0, gapJ = 0;
};
CouponVoxels couponVoxels(const printer_profiles::Profile& profile, const std::array<double, 3>& sizeMm, double gapMm);

// `count` bars of `sizes`: as many per row as the tray takes with the images' padding and alignment
// (printer_profiles::planJob decides), rows balanced. A bar too long for the tray stays alone in its
// row; planJob(profile, layout.bounds) then names the overhang.
CouponLayout planCouponLayout(const printer_profiles::Profile& profile, std::size_t count, const CouponVoxels& sizes);

// Bytes a coupon job of `layout` on `profile` needs with `bandLayers` per band: the writer's share
// (jobWriterBytes: its previews, per-layer images and the process), two bands of fractions (the next
// layer's slab too when the ditherer reads it) and the material of those bands and of the ditherer's
// kept trees (Ditherer::keptTrees), each holding whole 8-layer slabs of leaves, counted from the leaf
// types, and `ditherer`'s own buffers (materials::Ditherer::workingBytes at stageConcurrency(): error
// diffusion's layer slots over the bars' footprints). Measured on three 400 x 40 mm bars at 8 layers a
// band, white noise, 2 threads (2026-12-03): peak resident 1.33 GB at 1.5 mm tall, 1.54 GB at 15 mm and
// 1.55 GB at 150 mm (26 min), against 1.6 GiB (1.72 GB) estimated (the 5 bytes a band voxel counted
// before gave 1.1 GiB, under all three).
// Throws as jobWriterBytes does (a layout that planJob refuses). Thread-safe (pure).
std::uint64_t couponJobBytes(const CouponLayout& layout, const printer_profiles::Profile& profile, int contactSheetLayers,
                             int bandLayers, const materials::Ditherer& ditherer);

// Layers [k0, k1) of every bar (and layer k1 when asked), each voxel at its bar's fraction
// (`fractions[n]` for bar n), in the printer grid of `profile` with voxel (0,0,0) centred at `originMm`.
// `layout` and `fractions` must outlive the source. Throws common::Interrupted on a pending signal.
BandSource couponBands(const CouponLayout& layout, const std::vector<double>& fractions,
                       const printer_profiles::Profile& profile, const openvdb::Vec3d& originMm);

// The job's ditherer, counting the Vero and all voxels of every bar as the bands go by. Throws
// std::logic_error for a dithered voxel outside every bar.
class BarCountingDitherer final : public materials::Ditherer {
public:
  BarCountingDitherer(materials::Ditherer& inner, const CouponLayout& layout);
  std::string_view name() const override { return inner_.name(); }
  bool readsNextLayer() const override { return inner_.readsNextLayer(); }
  double workingBytes(const materials::DitherBand& band, int concurrency) const override {
    return inner_.workingBytes(band, concurrency);
  }
  std::size_t keptTrees() const override { return inner_.keptTrees(); }
  void reset() override;
  const std::vector<std::uint64_t>& vero() const { return vero_; }
  const std::vector<std::uint64_t>& voxels() const { return voxels_; }

protected:
  openvdb::BoolGrid::Ptr ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) override;

private:
  void countLeaf(const openvdb::BoolTree::LeafNodeType& leaf);
  materials::Ditherer& inner_;
  const CouponLayout& layout_;
  std::vector<std::uint64_t> vero_, voxels_;
};

// What the manifest and the --json summary record of each bar: index, specimen name, fraction,
// ditherer and seed, row and column, position and bounds (mm and voxels), size, the voxels and Vero
// voxels counted, the Vero share. Throws std::logic_error when a bar's count is not its volume.
nlohmann::json couponBarsJson(const CouponLayout& layout, const std::vector<double>& fractions,
                              const BarCountingDitherer& counted, std::uint64_t seed, const std::array<double, 3>& voxelMm);

}  // namespace rodfab::slicer
