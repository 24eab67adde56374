#include "slicer/job_pipeline.hpp"

#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "common/stopwatch.hpp"
#include "voxel/tree_assembly.hpp"

#include <tbb/global_control.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>
#include <tbb/task_scheduler_observer.h>

#include <pthread.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <vector>

namespace rodfab::slicer {

namespace {

using Clock = std::chrono::steady_clock;
using common::secondsSince;

using common::processCpuSeconds;

// The CPU time (user + system) of the threads while they are inside one task arena: TBB calls the
// observer on each thread as it enters and leaves, which reads that thread's own CPU clock; a thread
// still inside when seconds() is asked (a worker waiting for more) counts up to then. Each stage's
// arena runs only that stage's work, so this is the stage's CPU time, its threads' waiting included.
class ArenaCpuClock final : public tbb::task_scheduler_observer {
public:
  explicit ArenaCpuClock(tbb::task_arena& arena) : tbb::task_scheduler_observer(arena) { observe(true); }
  ArenaCpuClock(const ArenaCpuClock&) = delete;
  ArenaCpuClock& operator=(const ArenaCpuClock&) = delete;
  ~ArenaCpuClock() override { observe(false); }

  void on_scheduler_entry(bool) override {
    clockid_t clock{};
    if (::pthread_getcpuclockid(::pthread_self(), &clock) != 0) return;  // not counted rather than wrong
    const std::lock_guard lock(mutex_);
    for (Inside& t : inside_)
      if (t.thread == std::this_thread::get_id()) {
        ++t.depth;  // entered again before it left: its time counts once
        return;
      }
    inside_.push_back({std::this_thread::get_id(), clock, common::cpuClockSeconds(clock), 1});
  }
  void on_scheduler_exit(bool) override {
    const std::lock_guard lock(mutex_);
    for (auto t = inside_.begin(); t != inside_.end(); ++t)
      if (t->thread == std::this_thread::get_id()) {
        if (--t->depth > 0) return;
        done_ += common::cpuClockSeconds(t->clock) - t->entered;
        inside_.erase(t);
        return;
      }
  }
  double seconds() const {
    const std::lock_guard lock(mutex_);
    double total = done_;
    for (const Inside& t : inside_) total += common::cpuClockSeconds(t.clock) - t.entered;
    return total;
  }

private:
  struct Inside {
    std::thread::id thread;
    clockid_t clock;
    double entered;
    int depth;
  };
  mutable std::mutex mutex_;
  std::vector<Inside> inside_;
  double done_ = 0.0;
};

// One stage's own task arena: a thread waiting inside one stage (joining its parallel loops) never
// picks up another stage's tasks, so a band is not held up by work of the stages it overlaps.
// `run` adds the wall time of `f` to `busy`; it is called by one thread at a time (serial filters).
// cpuSeconds(): every thread's CPU time inside the arena so far (ArenaCpuClock).
class StageArena {
public:
  explicit StageArena(int concurrency) : arena_(concurrency), clock_(arena_) {}
  double cpuSeconds() const { return clock_.seconds(); }

  template <class F>
  void run(double& busy, F&& f) {
    const auto start = Clock::now();
    try {
      arena_.execute(std::forward<F>(f));
    } catch (...) {
      busy += secondsSince(start);
      throw;
    }
    busy += secondsSince(start);
  }

private:
  tbb::task_arena arena_;
  ArenaCpuClock clock_;  // after arena_: stops observing before the arena goes
};

// One band on its way through the stages.
struct Band {
  int k0 = 0, k1 = 0;
  BandGrids grids;
  openvdb::BoolGrid::Ptr material;
};

// The bands in flight, owned here rather than by the pipeline's tokens: when a stage throws, TBB's
// parallel_pipeline drops the items it holds between stages without destroying them (a band's grids,
// ~0.6 MB on a small test job, leaked per failed or interrupted slice; found by the sanitizer build).
// Its stages pass raw pointers; the bands die with this, whichever way streamJob leaves. A band's trees
// are let go of outside the pipeline's cancellation (voxel::outsideCancellation: in a cancelled stage
// OpenVDB would leak their nodes).
class BandsInFlight {
public:
  BandsInFlight() = default;
  BandsInFlight(const BandsInFlight&) = delete;
  BandsInFlight& operator=(const BandsInFlight&) = delete;
  ~BandsInFlight() {
    voxel::outsideCancellation([this] { bands_.clear(); });
  }
  Band* add() {
    std::lock_guard<std::mutex> lock(mutex_);
    return bands_.emplace_back(std::make_unique<Band>()).get();
  }
  void remove(const Band* band) {
    std::unique_ptr<Band> removed;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const auto found = std::find_if(bands_.begin(), bands_.end(), [band](const std::unique_ptr<Band>& b) { return b.get() == band; });
      removed = std::move(*found);
      bands_.erase(found);
    }
    voxel::outsideCancellation([&removed] { removed.reset(); });
  }
  // Lets go of the band's fractions, done with once it is dithered.
  static void releaseFractions(Band& band) {
    voxel::outsideCancellation([&band] { band.grids.fraction.reset(); });
  }

private:
  std::mutex mutex_;
  std::vector<std::unique_ptr<Band>> bands_;
};


}  // namespace

int bandEnd(int k0, int bandLayers) {
  const auto floorTo = [](int k, int step) { return k - ((k % step) + step) % step; };  // negative k too
  // A size dividing a slab: the next multiple of it, which never lies past k0's slab.
  if (kLeafLayers % bandLayers == 0) return floorTo(k0, bandLayers) + bandLayers;
  const int end = k0 + bandLayers;
  if (bandLayers % kLeafLayers != 0) return end;
  const int aligned = floorTo(end, kLeafLayers);
  return aligned > k0 ? aligned : end;
}

int stageConcurrency() {
  const std::size_t limit = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  const int arena = tbb::this_task_arena::max_concurrency();
  return std::max(1, limit < std::size_t(arena) ? int(limit) : arena);
}

std::uint64_t jobWriterBytes(const printer_profiles::Profile& profile, const openvdb::CoordBBox& partBounds,
                             int contactSheetLayers) {
  constexpr double kRuntimeBytes = 96.0 * (1 << 20), kLayerImageBytes = 30.0;
  const printer_profiles::JobGeometry geometry = printer_profiles::planJob(profile, partBounds);
  const double pixels = double(geometry.width) * double(geometry.height);
  return common::saturatedBytes(kRuntimeBytes + kLayerImageBytes * pixels +
                                double(printer_profiles::previewMemoryBytes(geometry, profile, contactSheetLayers)));
}

printer_profiles::JobResult streamJob(printer_profiles::JobSpec spec, const BandSource& source,
                                      materials::Ditherer& ditherer, const PipelineOptions& options,
                                      StageSeconds& seconds) {
  if (options.bandLayers < 1) throw std::invalid_argument("band size must be at least one layer");
  const openvdb::CoordBBox part = spec.partBounds;
  if (part.empty()) throw std::invalid_argument("the part has no layers to print");
  const bool readsNextLayer = ditherer.readsNextLayer();
  const int kFirst = part.min().z(), kLast = part.max().z(), layers = kLast - kFirst + 1;

  const int threads = stageConcurrency();
  StageArena sourceArena(threads), ditherArena(threads), emitArena(threads);
  const auto start = Clock::now();
  const double cpuStart = processCpuSeconds();
  const auto account = [&] {
    seconds.wall += secondsSince(start);
    seconds.cpu += processCpuSeconds() - cpuStart;
    seconds.sourceCpu += sourceArena.cpuSeconds();
    seconds.ditherCpu += ditherArena.cpuSeconds();
    seconds.emitCpu += emitArena.cpuSeconds();
  };
  try {
    std::optional<printer_profiles::JobWriter> writer;
    emitArena.run(seconds.emit, [&] { writer.emplace(std::move(spec)); });
    ditherer.reset();
    int nextK0 = kFirst;
    // Serial stages, kBandsInFlight (two) bands in flight: while the writer encodes band n, band n + 1 is made or
    // dithered. Three in flight (n + 2 made as well) held 2.6 GB where two hold 1.8 GB on a
    // 400 x 40 x 150 mm coupon block, and the torture suite's memory budget is 1.6 GiB. Each stage checks for an interrupt before it starts a band.
    BandsInFlight inFlight;
    const auto make = [&](tbb::flow_control& fc) -> Band* {
      if (nextK0 > kLast) {
        fc.stop();
        return nullptr;
      }
      common::throwIfInterrupted();
      Band* band = inFlight.add();
      band->k0 = nextK0;
      band->k1 = std::min(kLast + 1, bandEnd(nextK0, options.bandLayers));
      nextK0 = band->k1;
      const bool next = readsNextLayer && band->k1 <= kLast;
      sourceArena.run(seconds.source, [&] { band->grids = source(band->k0, band->k1, next); });
      return band;
    };
    const auto dither = [&](Band* band) {
      common::throwIfInterrupted();
      ditherArena.run(seconds.dither, [&] {
        band->material = options.ditherBand ? options.ditherBand(band->grids, band->k0, band->k1)
                                            : ditherer.ditherLayers(*band->grids.fraction, band->k0, band->k1);
      });
      BandsInFlight::releaseFractions(*band);  // done with: free them before the band waits
      return band;
    };
    const auto emit = [&](Band* band) {
      common::throwIfInterrupted();
      emitArena.run(seconds.emit, [&] { writer->addBand({band->material, band->grids.modulus, band->k0, band->k1}); });
      const int done = band->k1 - kFirst;
      inFlight.remove(band);
      if (options.onBand) options.onBand(done, layers);
    };
    tbb::parallel_pipeline(kBandsInFlight, tbb::make_filter<void, Band*>(tbb::filter_mode::serial_in_order, make) &
                                  tbb::make_filter<Band*, Band*>(tbb::filter_mode::serial_in_order, dither) &
                                  tbb::make_filter<Band*, void>(tbb::filter_mode::serial_in_order, emit));
    if (options.beforeFinalize) options.beforeFinalize(writer->metadata());
    printer_profiles::JobResult result;
    emitArena.run(seconds.emit, [&] { result = writer->finalize(); });
    account();
    return result;
  } catch (...) {
    account();
    throw;
  }
}

}  // namespace rodfab::slicer
