// 3D serpentine error diffusion, streamed layer by layer. Internal to materials/: callers use
// makeDitherer("error-diffusion").
#pragma once

#include "materials/band_leaves.hpp"
#include "materials/ditherer.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

namespace rodfab::materials {

// Floyd-Steinberg within a layer (rows along x, direction alternating with j + k), with a share of each
// voxel's error sent to the voxel above it in the next layer. Layers dithered alone would repeat nearly
// the same pattern, and a 3D low-pass would not average their error away; pushing most of the error
// straight up makes each layer fill the previous one's gaps (measured, 64 x 32 x 90 block at 0.3,
// RMS at 100 um: share 0 -> 0.008, 0.25 -> 0.007, 0.5 -> 0.0034, 0.8 -> 0.0016, 0.9 -> 0.0016 but more
// bias on thin rods; spreading the upward share over 3 x 3 neighbours was worse). Weights are renormalized over the
// neighbours that are inside the part, so error never leaks out through a boundary and thin rods keep
// their mean. The threshold is 0.5 jittered by +-kThresholdJitter/2 from a hash of (seed, i, j, k): it
// breaks up the regular "worms" plain error diffusion draws at simple fractions, and the seed chooses
// among equally good patterns.
//
// Threads: a band's layers are diffused as a wavefront on up to 4 of the arena's threads, the worker on
// layer k starting its row j once layer k - 1 has finished row j + 1. Every voxel then receives its error
// contributions in the order a single sweep gives them, so the pattern is bit for bit the same for any
// thread count (tests/test_materials_error_diffusion.cpp checks 1, 2 and 4 workers). A waiting worker
// sleeps on a condition variable, so oversubscribed cores cost time, not CPU. A worker that throws (an
// interrupt, std::bad_alloc) wakes the others, which stop; the first exception leaves ditherLayers. Each
// worker keeps its own Vero masks, merged after the band (layers k and k + 1 share the leaves' words).
// Measured with bench_dither on the shared 2-core machine (real-time priority, so the other sessions' load
// does not count): 27 -> 40 M voxels/s on the dense block, 28 -> 36 M/s on the rod bundle. Bands follow
// each other on one ditherer.
class ErrorDiffusionDitherer final : public Ditherer {
public:
  static constexpr float kShareToNextLayer = 0.8f;
  static constexpr float kThresholdJitter = 0.1f;

  explicit ErrorDiffusionDitherer(std::uint64_t seed, std::function<void()> checkInterrupt = {})
      : seed_(seed), checkInterrupt_(std::move(checkInterrupt)) {}
  // Not copyable: a copy would share buffers_ and race with the original on the same layers' lists.
  ErrorDiffusionDitherer(const ErrorDiffusionDitherer&) = delete;
  ErrorDiffusionDitherer& operator=(const ErrorDiffusionDitherer&) = delete;
  std::string_view name() const override { return "error-diffusion"; }
  bool readsNextLayer() const override { return true; }  // its last layer's error goes to layer k1

  // Workers of the wavefront in an arena of `concurrency` threads: layers form a chain, and more than
  // kMaxWorkers would only wait on each other.
  static constexpr int kMaxWorkers = 4;
  static int workersFor(int concurrency) { return concurrency < 1 ? 1 : concurrency > kMaxWorkers ? kMaxWorkers : concurrency; }
  // Layer slots of the wavefront: one per worker and kSpareSlots more (see BandDiffusion::prepare).
  static constexpr int kSpareSlots = 3;

  // What a band holds besides its grids, all of it counted from the types (error_diffusion.cpp):
  //  - the layer slots in use, min(workers + kSpareSlots, band layers + 1), each kSlotBytesPerVoxel a
  //    voxel of the fullest layer (its arrays at most 9/8 of it: Layer::resize's headroom), its rows (at
  //    most one a voxel and 8 a leaf, twice that after vector growth) and a word a leaf; kept from band
  //    to band (their capacity is the point);
  //  - the error carried to the next band, a Carry (12 bytes) per voxel of the last layer (reserved at
  //    the layer's size); kept;
  //  - each worker's Vero masks, one LeafMask (64 bytes) per leaf of the band, and the band's leaf lists
  //    (kListBytesPerLeaf), freed after the band.
  // Measured against the heap it keeps between bands (tests/test_materials_error_diffusion.cpp) and
  // against resident memory (slicer/README.md, "error diffusion's estimate"). Until tidy10 the arrays
  // and the carry were counted at twice their size (vector doubling) and the rows at one a voxel:
  // 434 bytes a voxel of a full 2000 x 1000 layer at 2 workers in 8-layer bands (5 slots), against 360
  // measured then.
  double workingBytes(const DitherBand& band, int concurrency) const override;
  std::size_t keptTrees() const override { return recycler_.keptTrees(); }
  void reset() override {
    started_ = false;
    carry_.clear();
  }

protected:
  openvdb::BoolGrid::Ptr ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) override;

private:
  struct Carry {
    int i, j;
    float error;
  };
  std::uint64_t seed_;
  std::function<void()> checkInterrupt_;  // DitherOptions::checkInterrupt
  bool started_ = false;
  int nextLayer_ = 0;
  std::vector<Carry> carry_;  // error waiting for layer nextLayer_, sorted by (j, i)
  // The layers' voxel lists and error, kept from band to band: layers of millions of voxels would
  // otherwise cost fresh allocations, their page faults and growth copies (error_diffusion.cpp).
  struct LayerBuffers;
  std::shared_ptr<LayerBuffers> buffers_;
  detail::OutputTreeRecycler recycler_;  // the output trees' nodes, reused from band to band
};

}  // namespace rodfab::materials
