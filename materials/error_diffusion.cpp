#include "materials/error_diffusion.hpp"

#include "materials/band_leaves.hpp"
#include "materials/counter_hash.hpp"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <condition_variable>
#include <mutex>
#include <limits>
#include <stdexcept>
#include <string>

#include <utility>

namespace rodfab::materials {

namespace {

using detail::BoolLeaf;
using detail::FloatLeaf;

struct Voxel {
  int i;
  float fraction;
  std::uint32_t leaf;     // index into the band's leaves
  std::uint16_t offset;   // within that leaf
};
struct Row {
  int j;
  std::uint32_t begin, end;  // voxels [begin, end), ascending i
};
// One layer's active voxels in (j, i) order.
struct Layer {
  int k = 0;
  std::vector<Voxel> voxels;
  std::vector<Row> rows;
};

int floorToLeaf(int k) { return k & ~static_cast<int>(FloatLeaf::DIM - 1); }

// Leaves are sorted by origin (z, y, x), so a slab's leaves are contiguous and grouped by y. Fills
// `layer` in place: a slot's vectors keep their capacity from the layer it held before (layers of
// millions of voxels otherwise cost a fresh allocation, its page faults and its growth copies each).
void enumerateLayer(const std::vector<const FloatLeaf*>& leaves, int k, Layer& layer) {
  layer.k = k;
  layer.voxels.clear();
  layer.rows.clear();
  const int z0 = floorToLeaf(k);
  auto first = std::lower_bound(leaves.begin(), leaves.end(), z0,
                                [](const FloatLeaf* l, int z) { return l->origin().z() < z; });
  auto last = std::lower_bound(first, leaves.end(), z0 + 1,
                               [](const FloatLeaf* l, int z) { return l->origin().z() < z; });
  const openvdb::Index dz = static_cast<openvdb::Index>(k - z0);
  for (auto group = first; group != last;) {
    const int y0 = (*group)->origin().y();
    auto groupEnd = std::find_if(group, last, [y0](const FloatLeaf* l) { return l->origin().y() != y0; });
    for (openvdb::Index dy = 0; dy < FloatLeaf::DIM; ++dy) {
      const auto begin = static_cast<std::uint32_t>(layer.voxels.size());
      for (auto it = group; it != groupEnd; ++it) {
        const FloatLeaf& leaf = **it;
        const float* values = leaf.buffer().data();
        for (openvdb::Index dx = 0; dx < FloatLeaf::DIM; ++dx) {
          const openvdb::Index n = (dx << 6) | (dy << 3) | dz;
          if (!leaf.isValueOn(n)) continue;
          layer.voxels.push_back({leaf.origin().x() + static_cast<int>(dx), values[n],
                                  static_cast<std::uint32_t>(it - leaves.begin()), static_cast<std::uint16_t>(n)});
        }
      }
      const auto end = static_cast<std::uint32_t>(layer.voxels.size());
      if (end > begin) layer.rows.push_back({y0 + static_cast<int>(dy), begin, end});
    }
    group = groupEnd;
  }
}

// Voxel indices of one row by x, for O(1) neighbour lookups; filled for a row and cleared after.
class RowIndex {
public:
  RowIndex(int xBase, int width) : xBase_(xBase), slots_(static_cast<std::size_t>(std::max(width, 0)) + 2, -1) {}
  void fill(const Layer& layer, const Row& row) {
    for (std::uint32_t v = row.begin; v < row.end; ++v) slot(layer.voxels[v].i) = static_cast<std::int32_t>(v);
  }
  void clear(const Layer& layer, const Row& row) {
    for (std::uint32_t v = row.begin; v < row.end; ++v) slot(layer.voxels[v].i) = -1;
  }
  // -1 outside the part (or outside the band's x range).
  std::int32_t at(int i) const {
    const int s = i - xBase_ + 1;
    return s >= 0 && s < static_cast<int>(slots_.size()) ? slots_[s] : -1;
  }

private:
  std::int32_t& slot(int i) { return slots_[static_cast<std::size_t>(i - xBase_ + 1)]; }
  int xBase_;
  std::vector<std::int32_t> slots_;
};

constexpr int kNoRowYet = std::numeric_limits<int>::min();
constexpr int kAllRows = std::numeric_limits<int>::max();
constexpr int kWakeSlackRows = 8;

// Thrown inside a waiting worker when another worker failed: the band is abandoned.
struct BandAbandoned {};

// A value one worker raises and others wait on: a short spin (the worker below is usually ahead), then
// asleep on a condition variable until it reaches `wakeAt` (>= atLeast; waking for a few rows more than
// needed lets a follower run that many before it can catch up and sleep again). Not std::atomic::wait:
// with GCC 12's libstdc++ a band hung in 2 of 3 benchmark runs, a wake-up lost. abandon() wakes every
// waiter with BandAbandoned, so a worker that failed never leaves the others asleep.
class Progress {
public:
  int get() const { return value_.load(std::memory_order_seq_cst); }
  // Takes the mutex only when someone sleeps: the waiter counts itself before it checks the value, the
  // publisher stores before it reads the count (both sequentially consistent), so one of them sees the
  // other and no wake-up is lost.
  void publish(int value) {
    value_.store(value, std::memory_order_seq_cst);
    if (sleepers_.load(std::memory_order_seq_cst) == 0) return;
    { std::lock_guard<std::mutex> lock(mutex_); }
    changed_.notify_all();
  }
  void abandon() {
    abandoned_.store(true, std::memory_order_seq_cst);
    { std::lock_guard<std::mutex> lock(mutex_); }
    changed_.notify_all();
  }
  void waitUntil(int atLeast, int wakeAt) {
    for (int spins = 0; spins < 256; ++spins) {
      if (get() >= atLeast) return;
      if (abandoned_.load(std::memory_order_relaxed)) throw BandAbandoned{};
    }
    std::unique_lock<std::mutex> lock(mutex_);
    sleepers_.fetch_add(1, std::memory_order_seq_cst);
    changed_.wait(lock, [&] { return get() >= wakeAt || abandoned_.load(std::memory_order_seq_cst); });
    sleepers_.fetch_sub(1, std::memory_order_seq_cst);
    if (get() < atLeast) throw BandAbandoned{};
  }
  void waitUntil(int atLeast) { waitUntil(atLeast, atLeast); }

private:
  std::atomic<int> value_{kNoRowYet};
  std::atomic<int> sleepers_{0};
  std::atomic<bool> abandoned_{false};
  std::mutex mutex_;
  std::condition_variable changed_;
};

// One layer of the band in flight: its voxels, the error they have received so far, and how far its
// diffusion has got (the j of the last finished row; kAllRows when the layer is done). `preparedFor`
// says which layer the slot holds: slots are reused round the ring.
struct LayerSlot {
  Layer layer;
  std::vector<float> error;
  Progress finishedThroughRow;
  Progress preparedFor;
};

// The slots' vectors between bands, swapped in and out (their capacity is what is kept).
struct SlotBuffers {
  std::vector<Layer> layers;
  std::vector<std::vector<float>> errors;
  SlotBuffers& lend(std::vector<LayerSlot>& slots) {
    layers.resize(std::max(layers.size(), slots.size()));
    errors.resize(layers.size());
    for (std::size_t n = 0; n < slots.size(); ++n) {
      std::swap(slots[n].layer, layers[n]);
      std::swap(slots[n].error, errors[n]);
    }
    return *this;
  }
  void giveBack(std::vector<LayerSlot>& slots) { lend(slots); }  // swapping again restores them
};

// Floyd-Steinberg weights: ahead in the row, then behind / below / ahead in the next row.
constexpr float kInLayer = 1.0f - ErrorDiffusionDitherer::kShareToNextLayer;
constexpr std::array<float, 4> kWeights{7.0f / 16 * kInLayer, 3.0f / 16 * kInLayer, 5.0f / 16 * kInLayer,
                                        1.0f / 16 * kInLayer};

// The diffusion of one band, layer by layer as a wavefront: the worker on layer k starts its row j once
// layer k - 1 has finished row j + 1. Row j of layer k receives error from row j of layer k - 1 (the
// share sent up) and from its own rows j - 1 and j; row j + 1 from row j. Waiting for row j + 1 below
// before writing into row j + 1 keeps every voxel's additions in the sequential sweep's order, so the
// floats, and the pattern, are the same for any number of workers.
class BandDiffusion {
public:
  // `buffers` lend the slots their vectors for the band (given back by the destructor).
  BandDiffusion(const std::vector<const FloatLeaf*>& leaves, std::vector<std::unique_ptr<BoolLeaf>>& out, int k0, int k1,
                std::uint64_t seed, const std::function<void()>& checkInterrupt, int workers, SlotBuffers& buffers)
      : leaves_(leaves), out_(out), k0_(k0), k1_(k1), seed_(seed), checkInterrupt_(checkInterrupt),
        slots_(static_cast<std::size_t>(workers) + 3), buffers_(buffers.lend(slots_)),
        rowWidth_(xRange(leaves)), nextLayer_(k0), veroByWorker_(static_cast<std::size_t>(workers)) {
    prepare(k0);
    prepare(k0 + 1);
  }
  ~BandDiffusion() { buffers_.giveBack(slots_); }
  BandDiffusion(const BandDiffusion&) = delete;
  BandDiffusion& operator=(const BandDiffusion&) = delete;
  LayerSlot& firstLayer() { return slot(k0_); }

  // Each worker claims the next layer until the band is done; a worker only ever waits for a layer
  // claimed before its own, whose worker is running, so one worker alone does the whole band. A worker
  // that throws abandons the band (waking the others) and keeps the first exception for rethrow().
  void work(int worker) {
    try {
      std::vector<detail::LeafMask>& vero = veroByWorker_[static_cast<std::size_t>(worker)];
      vero.resize(leaves_.size());
      RowIndex nextRowIndex(rowWidth_.first, rowWidth_.second), aboveIndex(rowWidth_.first, rowWidth_.second);
      for (int k = nextLayer_.fetch_add(1); k < k1_; k = nextLayer_.fetch_add(1)) {
        if (checkInterrupt_) checkInterrupt_();
        // Two layers ahead: the worker that claims k + 1 next must not wait for the enumeration.
        if (k + 2 <= k1_) prepare(k + 2);
        slot(k).preparedFor.waitUntil(k);
        slot(k + 1).preparedFor.waitUntil(k + 1);
        diffuseLayer(k, nextRowIndex, aboveIndex, vero);
      }
    } catch (const BandAbandoned&) {
    } catch (...) {
      abandon(std::current_exception());
    }
  }
  // After work(): throws what a worker threw.
  void rethrow() const {
    if (failure_) std::rethrow_exception(failure_);
  }
  // After work(): the error left for layer k1.
  const LayerSlot& lastLayer() { return slot(k1_); }
  // After work(): sets the Vero bits the workers found (each its own masks: layers k and k + 1 share
  // the leaves' words, and a shared atomic OR made the two workers fight over their cache lines).
  void storeVero() {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, out_.size()), [&](const tbb::blocked_range<std::size_t>& range) {
      for (std::size_t l = range.begin(); l != range.end(); ++l) {
        if (!out_[l]) continue;
        auto* words = out_[l]->buffer().data();
        for (const auto& vero : veroByWorker_)
          if (!vero.empty())
            for (openvdb::Index w = 0; w < detail::LeafMask::WORD_COUNT; ++w) words[w] |= vero[l].template getWord<std::uint64_t>(w);
      }
    });
  }
  const detail::FractionCheck& check() const { return check_; }

private:
  static std::pair<int, int> xRange(const std::vector<const FloatLeaf*>& leaves) {
    int xMin = 0, xMax = -1;
    for (std::size_t l = 0; l < leaves.size(); ++l) {
      xMin = l == 0 ? leaves[l]->origin().x() : std::min(xMin, leaves[l]->origin().x());
      xMax = l == 0 ? leaves[l]->origin().x() + 7 : std::max(xMax, leaves[l]->origin().x() + 7);
    }
    return {xMin, xMax - xMin + 1};
  }
  LayerSlot& slot(int k) { return slots_[static_cast<std::size_t>(k - k0_) % slots_.size()]; }

  void abandon(std::exception_ptr failure) {
    {
      std::lock_guard<std::mutex> lock(failureMutex_);
      if (!failure_) failure_ = std::move(failure);
    }
    for (LayerSlot& s : slots_) {
      s.finishedThroughRow.abandon();
      s.preparedFor.abandon();
    }
  }

  // A slot is read by three workers: its own layer's, the one below (which sends error up into it) and
  // the one above (which waits on its progress). So the slot of layer k - slots is reused for k once
  // layer k - slots + 1 is done (layers finish in order). The worker on layer j prepares j + 2, and at
  // most `workers` layers are in progress, the last ones claimed, so with slots = workers + 3 that layer
  // is done by then; the wait makes it a guarantee.
  void prepare(int k) {
    LayerSlot& s = slot(k);
    const int lastReader = k - static_cast<int>(slots_.size()) + 1;
    if (lastReader > k0_) slot(lastReader).finishedThroughRow.waitUntil(kAllRows);
    enumerateLayer(leaves_, k, s.layer);
    s.error.assign(s.layer.voxels.size(), 0.0f);
    s.finishedThroughRow.publish(kNoRowYet);
    s.preparedFor.publish(k);
  }

  void diffuseLayer(int k, RowIndex& nextRowIndex, RowIndex& aboveIndex, std::vector<detail::LeafMask>& vero) {
    LayerSlot& here = slot(k);
    LayerSlot& above = slot(k + 1);
    Progress* below = k > k0_ ? &slot(k - 1).finishedThroughRow : nullptr;
    const Layer& layer = here.layer;
    std::size_t aboveRow = 0;
    for (std::size_t r = 0; r < layer.rows.size(); ++r) {
      const Row& row = layer.rows[r];
      if (below) below->waitUntil(row.j + 1, row.j + 1 + kWakeSlackRows);
      const Row* nextRow = r + 1 < layer.rows.size() && layer.rows[r + 1].j == row.j + 1 ? &layer.rows[r + 1] : nullptr;
      while (aboveRow < above.layer.rows.size() && above.layer.rows[aboveRow].j < row.j) ++aboveRow;
      const Row* rowAbove =
          aboveRow < above.layer.rows.size() && above.layer.rows[aboveRow].j == row.j ? &above.layer.rows[aboveRow] : nullptr;
      if (nextRow) nextRowIndex.fill(layer, *nextRow);
      if (rowAbove) aboveIndex.fill(above.layer, *rowAbove);
      diffuseRow(k, layer, row, nextRow ? &nextRowIndex : nullptr, rowAbove ? &aboveIndex : nullptr, here.error, above.error,
                 vero);
      if (nextRow) nextRowIndex.clear(layer, *nextRow);
      if (rowAbove) aboveIndex.clear(above.layer, *rowAbove);
      here.finishedThroughRow.publish(row.j);
    }
    if (below) below->waitUntil(kAllRows);  // layers finish in order: see prepare()
    here.finishedThroughRow.publish(kAllRows);
  }

  // The serpentine sweep of one row (direction alternating with j + k), each voxel's error sent to the
  // neighbours inside the part, weights renormalized over them.
  void diffuseRow(int k, const Layer& layer, const Row& row, const RowIndex* nextRowIndex, const RowIndex* aboveIndex,
                  std::vector<float>& error, std::vector<float>& errorAbove, std::vector<detail::LeafMask>& vero) {
    const int dir = ((row.j + k) & 1) ? -1 : +1;
    const auto count = static_cast<std::int64_t>(row.end - row.begin);
    for (std::int64_t step = 0; step < count; ++step) {
      const std::uint32_t v = dir > 0 ? row.begin + static_cast<std::uint32_t>(step) : row.end - 1 - static_cast<std::uint32_t>(step);
      const Voxel& voxel = layer.voxels[v];
      const float f = voxel.fraction;
      if (!detail::FractionCheck::valid(f)) {
        check_.fail(voxel.leaf, voxel.offset);
        continue;
      }
      const float wanted = f + error[v];
      const float threshold = 0.5f + ErrorDiffusionDitherer::kThresholdJitter * (voxelUniform(seed_, voxel.i, row.j, k) - 0.5f);
      const bool isVero = f >= 1.0f || (f > 0.0f && wanted >= threshold);
      if (isVero) vero[voxel.leaf].setOn(voxel.offset);
      const float residual = wanted - (isVero ? 1.0f : 0.0f);

      std::array<std::int32_t, 4> targets{-1, -1, -1, -1};
      if (step + 1 < count) {
        const std::uint32_t a = dir > 0 ? v + 1 : v - 1;
        if (layer.voxels[a].i == voxel.i + dir) targets[0] = static_cast<std::int32_t>(a);
      }
      if (nextRowIndex) {
        targets[1] = nextRowIndex->at(voxel.i - dir);
        targets[2] = nextRowIndex->at(voxel.i);
        targets[3] = nextRowIndex->at(voxel.i + dir);
      }
      const std::int32_t up = aboveIndex ? aboveIndex->at(voxel.i) : -1;
      float total = up >= 0 ? ErrorDiffusionDitherer::kShareToNextLayer : 0.0f;
      for (int t = 0; t < 4; ++t)
        if (targets[t] >= 0) total += kWeights[t];
      if (total <= 0.0f) continue;  // an isolated voxel with nothing after it: its error has nowhere to go
      const float scale = residual / total;
      for (int t = 0; t < 4; ++t)
        if (targets[t] >= 0) error[static_cast<std::size_t>(targets[t])] += kWeights[t] * scale;
      if (up >= 0) errorAbove[static_cast<std::size_t>(up)] += ErrorDiffusionDitherer::kShareToNextLayer * scale;
    }
  }

  const std::vector<const FloatLeaf*>& leaves_;
  std::vector<std::unique_ptr<BoolLeaf>>& out_;
  const int k0_, k1_;
  const std::uint64_t seed_;
  const std::function<void()>& checkInterrupt_;
  std::vector<LayerSlot> slots_;
  SlotBuffers& buffers_;
  const std::pair<int, int> rowWidth_;  // x of the band's first column and the number of columns
  std::atomic<int> nextLayer_;
  std::vector<std::vector<detail::LeafMask>> veroByWorker_;
  detail::FractionCheck check_;
  std::mutex failureMutex_;
  std::exception_ptr failure_;
};

// The previous band's error for layer k0, matched by (j, i): both lists are in that order.
template <class Carries>
void takeCarry(const Carries& carry, LayerSlot& first, int k0) {
  const Layer& layer = first.layer;
  std::size_t r = 0, v = 0;
  for (const auto& c : carry) {
    while (r < layer.rows.size() && layer.rows[r].j < c.j) ++r;
    bool found = false;
    if (r < layer.rows.size() && layer.rows[r].j == c.j) {
      v = std::max<std::size_t>(v, layer.rows[r].begin);
      while (v < layer.rows[r].end && layer.voxels[v].i < c.i) ++v;
      found = v < layer.rows[r].end && layer.voxels[v].i == c.i;
    }
    if (!found)
      throw std::logic_error("error-diffusion: voxel (" + std::to_string(c.i) + ", " + std::to_string(c.j) + ", " +
                             std::to_string(k0) + ") was inside the part one layer past the previous band but "
                             "is not in this band's grid: consecutive bands' grids disagree");
    first.error[v] = c.error;
  }
}

}  // namespace

struct ErrorDiffusionDitherer::LayerBuffers : SlotBuffers {};

openvdb::BoolGrid::Ptr ErrorDiffusionDitherer::ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) {
  if (started_ && k0 != nextLayer_)
    throw std::logic_error("error-diffusion: bands must follow each other: expected a band starting at layer " +
                           std::to_string(nextLayer_) + ", got " + std::to_string(k0) + " (reset() to start over)");
  // One layer past the band: its active voxels decide where the last layer's error may go.
  const std::vector<const FloatLeaf*> leaves = detail::leavesInLayers(fraction.tree(), k0, k1 + 1);
  std::vector<std::unique_ptr<BoolLeaf>> out(leaves.size());
  for (std::size_t l = 0; l < leaves.size(); ++l) {
    const detail::LeafMask mask = detail::activeInLayers(*leaves[l], k0, k1);
    if (mask.isOff()) continue;
    out[l] = std::make_unique<BoolLeaf>(leaves[l]->origin(), false, false);
    out[l]->setValueMask(mask);
  }
  if (k0 == k1) return detail::assembleMaterialGrid(out, fraction);

  // Layers form a chain; more than a few workers would only wait on each other.
  const int workers = std::clamp(tbb::this_task_arena::max_concurrency(), 1, 4);
  if (!buffers_) buffers_ = std::make_shared<LayerBuffers>();
  BandDiffusion band(leaves, out, k0, k1, seed_, checkInterrupt_, workers, *buffers_);
  if (started_) takeCarry(carry_, band.firstLayer(), k0);
  tbb::parallel_for(0, workers, [&](int worker) { band.work(worker); });
  band.rethrow();
  band.storeVero();
  band.check().throwIfFailed(fraction, leaves);

  carry_.clear();
  const LayerSlot& last = band.lastLayer();
  for (const Row& row : last.layer.rows)
    for (std::uint32_t v = row.begin; v < row.end; ++v)
      if (last.error[v] != 0.0f) carry_.push_back({last.layer.voxels[v].i, row.j, last.error[v]});
  started_ = true;
  nextLayer_ = k1;
  return detail::assembleMaterialGrid(out, fraction);
}

}  // namespace rodfab::materials
