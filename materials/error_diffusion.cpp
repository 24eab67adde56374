// Error diffusion's sweep: a band's layers diffused as a wavefront on up to 4 threads (BandDiffusion),
// the error carried from band to band. The layers' preparation is error_diffusion_layers.cpp.
#include "materials/error_diffusion.hpp"

#include "materials/band_leaves.hpp"
#include "materials/error_diffusion_layers.hpp"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <limits>
#include <stdexcept>
#include <string>
#include <tuple>

#include <utility>

namespace rodfab::materials {

namespace {

using namespace detail;  // leaves, Layer and its Link bits, the preparation steps
using Row = LayerRow;

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

// The neighbours' total weight for each combination of Link bits, in a row swept towards +x (Dir = 1)
// or -x: the share sent up first, then the weights in kWeights' order, added as the sweep always added
// them (the floats must come out the same).
template <int Dir>
std::array<float, 64> totalWeights() {
  constexpr unsigned ahead = Dir > 0 ? kRight : kLeft, behind = Dir > 0 ? kNextLeft : kNextRight;
  constexpr unsigned aheadNext = Dir > 0 ? kNextRight : kNextLeft;
  constexpr std::array<unsigned, 4> role{ahead, behind, kNextSame, aheadNext};
  std::array<float, 64> totals{};
  for (unsigned links = 0; links < 64; ++links) {
    float total = (links & kUp) ? ErrorDiffusionDitherer::kShareToNextLayer : 0.0f;
    for (int t = 0; t < 4; ++t)
      if (links & role[t]) total += kWeights[t];
    totals[links] = total;
  }
  return totals;
}

// `yes` if `condition`, else `no`, by masking the bits: a branch on a dithering decision would be
// mispredicted about as often as it is taken.
inline float select(bool condition, float yes, float no) {
  const std::uint32_t mask = 0u - static_cast<std::uint32_t>(condition);
  return std::bit_cast<float>((std::bit_cast<std::uint32_t>(yes) & mask) | (std::bit_cast<std::uint32_t>(no) & ~mask));
}

// The diffusion of one band, layer by layer as a wavefront: the worker on layer k starts its row j once
// layer k - 1 has finished row j + 1. Row j of layer k receives error from row j of layer k - 1 (the
// share sent up) and from its own rows j - 1 and j; row j + 1 from row j. Waiting for row j + 1 below
// before writing into row j + 1 keeps every voxel's additions in the sequential sweep's order, so the
// floats, and the pattern, are the same for any number of workers.
class BandDiffusion {
public:
  // `buffers` lend the slots their vectors for the band (given back by the destructor).
  BandDiffusion(const std::vector<const FloatLeaf*>& leaves, const std::vector<BoolLeaf*>& out, int k0, int k1,
                std::uint64_t seed, const std::function<void()>& checkInterrupt, int workers, SlotBuffers& buffers)
      : leaves_(leaves), out_(out), k0_(k0), k1_(k1), seed_(seed), checkInterrupt_(checkInterrupt),
        slots_(static_cast<std::size_t>(workers + ErrorDiffusionDitherer::kSpareSlots)), buffers_(buffers.lend(slots_)),
        nextLayer_(k0), veroByWorker_(static_cast<std::size_t>(workers)) {
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
      std::vector<LeafMask>& vero = veroByWorker_[static_cast<std::size_t>(worker)];
      vero.resize(leaves_.size());
      for (int k = nextLayer_.fetch_add(1); k < k1_; k = nextLayer_.fetch_add(1)) {
        if (checkInterrupt_) checkInterrupt_();
        // Two layers ahead: the worker that claims k + 1 next must not wait for the enumeration.
        if (k + 2 <= k1_) prepare(k + 2);
        slot(k).preparedFor.waitUntil(k);
        slot(k + 1).preparedFor.waitUntil(k + 1);
        diffuseLayer(k, vero);
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
        auto* words = out_[l]->buffer().data();  // a reused leaf holds an earlier band's values
        for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) words[w] = 0;
        for (const auto& vero : veroByWorker_)
          if (!vero.empty())
            for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) words[w] |= vero[l].template getWord<std::uint64_t>(w);
      }
    });
  }
  const FractionCheck& check() const { return check_; }

private:
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
    if (k < k1_) computeThresholds(seed_, ErrorDiffusionDitherer::kThresholdJitter, s.layer);  // layer k1 is only where error may go
    linkWithinLayer(s.layer);
    s.error.assign(s.layer.size(), 0.0f);
    if (k > k0_) {
      // Layer k - 1's up links, before anyone sweeps it: its worker waits for this slot to be prepared.
      LayerSlot& below = slot(k - 1);
      below.preparedFor.waitUntil(k - 1);
      linkUp(below.layer, s.layer);
    }
    s.finishedThroughRow.publish(kNoRowYet);
    s.preparedFor.publish(k);
  }

  void diffuseLayer(int k, std::vector<LeafMask>& vero) {
    LayerSlot& here = slot(k);
    float* errorAbove = slot(k + 1).error.data();
    Progress* below = k > k0_ ? &slot(k - 1).finishedThroughRow : nullptr;
    for (const Row& row : here.layer.rows) {
      if (below) below->waitUntil(row.j + 1, row.j + 1 + kWakeSlackRows);
      if ((row.j + k) & 1)
        diffuseRow<-1>(here.layer, row, here.error.data(), errorAbove, vero);
      else
        diffuseRow<+1>(here.layer, row, here.error.data(), errorAbove, vero);
      here.finishedThroughRow.publish(row.j);
    }
    if (below) below->waitUntil(kAllRows);  // layers finish in order: see prepare()
    here.finishedThroughRow.publish(kAllRows);
  }

  // The serpentine sweep of one row (towards +x for Dir = 1), each voxel's error sent to the neighbours
  // inside the part, weights renormalized over them. Everything about the neighbours was worked out
  // when the layers were prepared. The error carried from voxel to voxel is the loop's critical path
  // (add, compare, divide, multiply, add): the share sent ahead stays in a register instead of making a
  // round trip through memory, and both outcomes' divisions start before the comparison settles. The
  // floats are the same: the share ahead is still added last, as the single sweep adds it.
  template <int Dir>
  void diffuseRow(const Layer& layer, const Row& row, float* error, float* errorAbove, std::vector<LeafMask>& vero) {
    static const std::array<float, 64> totals = totalWeights<Dir>();
    constexpr unsigned ahead = Dir > 0 ? kRight : kLeft;
    constexpr unsigned behind = Dir > 0 ? kNextLeft : kNextRight, aheadNext = Dir > 0 ? kNextRight : kNextLeft;
    const std::int64_t first = Dir > 0 ? row.begin : static_cast<std::int64_t>(row.end) - 1;
    const std::int64_t stop = Dir > 0 ? row.end : static_cast<std::int64_t>(row.begin) - 1;
    float sentAhead = 0.0f;  // what the voxel before sent to this one, when it sent anything
    bool received = false;
    for (std::int64_t v = first; v != stop; v += Dir) {
      const bool hasSentAhead = std::exchange(received, false);
      const float f = layer.fraction[v];
      if (!FractionCheck::valid(f)) {
        check_.fail(layer.leaf[v], layer.offset[v]);
        continue;
      }
      const float wanted = f + (hasSentAhead ? error[v] + sentAhead : error[v]);
      const bool isVero = (f >= 1.0f) | ((f > 0.0f) & (wanted >= layer.threshold[v]));
      const unsigned offset = layer.offset[v];
      vero[layer.leaf[v]].template getWord<std::uint64_t>(offset >> 6) |= std::uint64_t{isVero} << (offset & 63);
      const unsigned links = layer.links[v];
      const float total = totals[links];
      if (total <= 0.0f) continue;  // an isolated voxel with nothing after it: its error has nowhere to go
      // residual / total for residual = wanted - 1 (Vero) or wanted - 0 (= wanted, bit for bit).
      const float scale = select(isVero, (wanted - 1.0f) / total, wanted / total);
      sentAhead = kWeights[0] * scale;
      received = (links & ahead) != 0;
      // The next row's voxels at i - 1, i, i + 1, those that are inside the part, in that order.
      const std::uint32_t left = layer.nextRow[v];
      const std::uint32_t same = left + ((links & kNextLeft) ? 1 : 0);
      const std::uint32_t right = same + ((links & kNextSame) ? 1 : 0);
      if (links & behind) error[Dir > 0 ? left : right] += kWeights[1] * scale;
      if (links & kNextSame) error[same] += kWeights[2] * scale;
      if (links & aheadNext) error[Dir > 0 ? right : left] += kWeights[3] * scale;
      if (links & kUp) errorAbove[layer.up[v]] += ErrorDiffusionDitherer::kShareToNextLayer * scale;
    }
  }

  const std::vector<const FloatLeaf*>& leaves_;
  const std::vector<BoolLeaf*>& out_;  // by leaf, null where the leaf has no voxel in the band
  const int k0_, k1_;
  const std::uint64_t seed_;
  const std::function<void()>& checkInterrupt_;
  std::vector<LayerSlot> slots_;
  SlotBuffers& buffers_;
  std::atomic<int> nextLayer_;
  std::vector<std::vector<LeafMask>> veroByWorker_;
  FractionCheck check_;
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
      while (v < layer.rows[r].end && layer.i[v] < c.i) ++v;
      found = v < layer.rows[r].end && layer.i[v] == c.i;
    }
    if (!found)
      throw std::logic_error("error-diffusion: voxel (" + std::to_string(c.i) + ", " + std::to_string(c.j) + ", " +
                             std::to_string(k0) + ") was inside the part one layer past the previous band but "
                             "is not in this band's grid: consecutive bands' grids disagree");
    first.error[v] = c.error;
  }
}

// The band's leaves sorted by origin (z, y, x), as the layers are enumerated, and the output leaf of
// each (null where the leaf has no voxel in the band's layers).
struct BandLeaves {
  std::vector<const FloatLeaf*> leaves;
  std::vector<BoolLeaf*> out;
};

// Sorts `groups`' leaves and makes the output leaves, in `out` (groups' order, for the recycler's
// assembly), from `spares` where it has any: a slicer's thousands of bands then reuse the first bands'
// output nodes instead of allocating and zeroing new ones (malloc, memset and page faults were a third
// of the lattice bands' time in bench_dither). The leaves' values are set by storeVero.
BandLeaves bandLeaves(const LeafGroups& groups, int k0, int k1, SpareNodes& spares, std::vector<std::unique_ptr<BoolLeaf>>& out) {
  std::vector<std::size_t> order(groups.leaves.size());
  for (std::size_t g = 0; g < order.size(); ++g) order[g] = g;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const openvdb::Coord& p = groups.leaves[a]->origin();
    const openvdb::Coord& q = groups.leaves[b]->origin();
    return std::tuple(p.z(), p.y(), p.x()) < std::tuple(q.z(), q.y(), q.x());
  });
  BandLeaves band{std::vector<const FloatLeaf*>(order.size()), std::vector<BoolLeaf*>(order.size(), nullptr)};
  for (std::size_t l = 0; l < order.size(); ++l) {
    const std::size_t g = order[l];
    band.leaves[l] = groups.leaves[g];
    const LeafMask mask = activeInLayers(*groups.leaves[g], k0, k1);
    if (mask.isOff()) continue;
    out[g] = spares.leaf(g, groups.leaves[g]->origin());
    out[g]->setValueMask(mask);
    band.out[l] = out[g].get();
  }
  return band;
}

}  // namespace

struct ErrorDiffusionDitherer::LayerBuffers : SlotBuffers {};

namespace {

// A slot's bytes per voxel of its layer: Layer's per-voxel arrays, at most 9/8 of the fullest layer
// the slot held (Layer::resize's headroom, kLayerHeadroom), and the error (assign(): exactly its size).
constexpr double kVoxelArrayBytes =
    double(sizeof(int) + 2 * sizeof(float) + 3 * sizeof(std::uint32_t) + sizeof(std::uint16_t) + sizeof(std::uint8_t));
static_assert(kVoxelArrayBytes == 27.0);
constexpr double kSlotBytesPerVoxel = kVoxelArrayBytes * (1.0 + 1.0 / double(kLayerHeadroom)) + double(sizeof(float));
// A slot's rows (push_back: up to twice their count after growth), and its scratch of a word per leaf
// of the layer's slab (leafRows, resize: the same).
constexpr double kSlotBytesPerRow = 2.0 * double(sizeof(LayerRow));
constexpr double kSlotBytesPerLeaf = 2.0 * double(sizeof(std::uint64_t));
// The band's leaf lists: the groups' leaves, the sort order, the output leaves (by group), the sorted
// leaves and their output pointers (BandLeaves), 8 bytes a leaf each.
constexpr double kListBytesPerLeaf = 5.0 * 8.0;

}  // namespace

double ErrorDiffusionDitherer::workingBytes(const DitherBand& band, int concurrency) const {
  const int workers = workersFor(concurrency);
  const double slots = std::min(workers + kSpareSlots, std::max(band.layers, 1) + 1);
  // A layer's rows: at most one a voxel, and 8 a leaf of its slab (a leaf spans 8 rows), which the
  // band's leaves bound (the band holds the slab of each of its layers and of the next one).
  const double rows = std::min(band.layerVoxels, double(FloatLeaf::DIM) * band.leaves);
  const double slotBytes = kSlotBytesPerVoxel * band.layerVoxels + kSlotBytesPerRow * rows + kSlotBytesPerLeaf * band.leaves;
  const double carryBytes = double(sizeof(Carry)) * band.layerVoxels;  // reserved at most a layer's size
  const double maskBytes = double(workers) * double(sizeof(LeafMask)) * band.leaves;
  return slots * slotBytes + carryBytes + maskBytes + kListBytesPerLeaf * band.leaves;
}

openvdb::BoolGrid::Ptr ErrorDiffusionDitherer::ditherLeafVoxels(const openvdb::FloatGrid& fraction, int k0, int k1) {
  if (started_ && k0 != nextLayer_)
    throw std::logic_error("error-diffusion: bands must follow each other: expected a band starting at layer " +
                           std::to_string(nextLayer_) + ", got " + std::to_string(k0) + " (reset() to start over)");
  // One layer past the band: its active voxels decide where the last layer's error may go.
  const detail::LeafGroups groups = detail::leafGroupsInLayers(fraction.tree(), k0, k1 + 1);
  detail::SpareNodes spares = recycler_.takeSpares();
  std::vector<std::unique_ptr<BoolLeaf>> out(groups.leaves.size());  // in the groups' order
  const BandLeaves band = bandLeaves(groups, k0, k1, spares, out);
  if (k0 == k1) return detail::materialGrid(recycler_.assemble(groups, out, spares), fraction);
  const std::vector<const FloatLeaf*>& leaves = band.leaves;

  const int workers = workersFor(tbb::this_task_arena::max_concurrency());
  if (!buffers_) buffers_ = std::make_shared<LayerBuffers>();
  BandDiffusion diffusion(leaves, band.out, k0, k1, seed_, checkInterrupt_, workers, *buffers_);
  if (started_) takeCarry(carry_, diffusion.firstLayer(), k0);
  tbb::parallel_for(0, workers, [&](int worker) { diffusion.work(worker); });
  diffusion.rethrow();
  diffusion.storeVero();
  diffusion.check().throwIfFailed(fraction, leaves);

  carry_.clear();
  const LayerSlot& last = diffusion.lastLayer();
  carry_.reserve(last.layer.size());  // exactly, not push_back's doubling: workingBytes counts a Carry a voxel
  for (const Row& row : last.layer.rows)
    for (std::uint32_t v = row.begin; v < row.end; ++v)
      if (last.error[v] != 0.0f) carry_.push_back({last.layer.i[v], row.j, last.error[v]});
  started_ = true;
  nextLayer_ = k1;
  return detail::materialGrid(recycler_.assemble(groups, out, spares), fraction);
}

}  // namespace rodfab::materials
