#include "slicer/job_pipeline.hpp"

#include "common/stopwatch.hpp"

#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>
#include <tbb/task_scheduler_observer.h>

#include <pthread.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <unordered_map>

namespace rodfab::slicer {

namespace {

using Clock = std::chrono::steady_clock;
using common::secondsSince;

std::int64_t cpuNanoseconds(clockid_t clock) {
  timespec t{};
  if (::clock_gettime(clock, &t) != 0) return 0;
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
}

// The CPU time of the threads while they work in one task arena: from when a thread joins the arena
// to when it leaves, read from its thread CPU clock.
class ArenaCpuClock final : public tbb::task_scheduler_observer {
public:
  explicit ArenaCpuClock(tbb::task_arena& arena) : tbb::task_scheduler_observer(arena) { observe(true); }
  ~ArenaCpuClock() override { observe(false); }
  ArenaCpuClock(const ArenaCpuClock&) = delete;
  ArenaCpuClock& operator=(const ArenaCpuClock&) = delete;

  // Seconds so far, threads still in the arena included.
  double seconds() const {
    std::lock_guard lock(mutex_);
    std::int64_t ns = finishedNs_;
    for (const auto& [thread, entry] : inside_) ns += cpuNanoseconds(entry.clock) - entry.startNs;
    return static_cast<double>(ns) * 1e-9;
  }

  void on_scheduler_entry(bool) override {
    clockid_t clock{};
    if (::pthread_getcpuclockid(::pthread_self(), &clock) != 0) return;
    const std::int64_t now = cpuNanoseconds(clock);
    std::lock_guard lock(mutex_);
    inside_[::pthread_self()] = {clock, now};
  }
  void on_scheduler_exit(bool) override {
    std::lock_guard lock(mutex_);
    const auto it = inside_.find(::pthread_self());
    if (it == inside_.end()) return;
    finishedNs_ += cpuNanoseconds(it->second.clock) - it->second.startNs;
    inside_.erase(it);
  }

private:
  struct Entry {
    clockid_t clock;
    std::int64_t startNs;
  };
  mutable std::mutex mutex_;
  std::unordered_map<pthread_t, Entry> inside_;
  std::int64_t finishedNs_ = 0;
};

// One stage's own task arena and its CPU clock. Threads in one arena never run another arena's tasks
// (not even while they wait), so a stage is not charged for the work of the stages it overlaps.
class StageArena {
public:
  explicit StageArena(int concurrency) : arena_(concurrency), clock_((arena_.initialize(), arena_)) {}

  template <class F>
  void run(F&& f) {
    arena_.execute(std::forward<F>(f));
  }
  double cpuSeconds() const { return clock_.seconds(); }

private:
  tbb::task_arena arena_;
  ArenaCpuClock clock_;
};

// One band on its way through the stages.
struct Band {
  int k0 = 0, k1 = 0;
  BandGrids grids;
  openvdb::BoolGrid::Ptr material;
};

}  // namespace

printer_profiles::JobResult streamJob(printer_profiles::JobSpec spec, const BandSource& source,
                                      materials::Ditherer& ditherer, const PipelineOptions& options,
                                      StageSeconds& seconds) {
  if (options.bandLayers < 1) throw std::invalid_argument("band size must be at least one layer");
  const openvdb::CoordBBox part = spec.partBounds;
  if (part.empty()) throw std::invalid_argument("the part has no layers to print");
  const bool readsNextLayer = ditherer.name() == "error-diffusion";
  const int kFirst = part.min().z(), kLast = part.max().z(), layers = kLast - kFirst + 1;

  const auto start = Clock::now();
  const int threads = tbb::this_task_arena::max_concurrency();
  StageArena sourceArena(threads), ditherArena(threads), emitArena(threads);
  const auto account = [&] {
    seconds.source += sourceArena.cpuSeconds();
    seconds.dither += ditherArena.cpuSeconds();
    seconds.emit += emitArena.cpuSeconds();
    seconds.wall += secondsSince(start);
  };
  try {
    std::optional<printer_profiles::JobWriter> writer;
    emitArena.run([&] { writer.emplace(std::move(spec)); });
    ditherer.reset();
    int nextK0 = kFirst;
    // One token per stage: each stage works on its own band, in order.
    tbb::parallel_pipeline(
        3,
        tbb::make_filter<void, std::shared_ptr<Band>>(tbb::filter_mode::serial_in_order,
                                                      [&](tbb::flow_control& fc) -> std::shared_ptr<Band> {
                                                        if (nextK0 > kLast) {
                                                          fc.stop();
                                                          return nullptr;
                                                        }
                                                        auto band = std::make_shared<Band>();
                                                        band->k0 = nextK0;
                                                        band->k1 = std::min(kLast + 1, nextK0 + options.bandLayers);
                                                        nextK0 = band->k1;
                                                        const bool next = readsNextLayer && band->k1 <= kLast;
                                                        sourceArena.run([&] { band->grids = source(band->k0, band->k1, next); });
                                                        return band;
                                                      }) &
            tbb::make_filter<std::shared_ptr<Band>, std::shared_ptr<Band>>(
                tbb::filter_mode::serial_in_order,
                [&](std::shared_ptr<Band> band) {
                  ditherArena.run([&] { band->material = ditherer.ditherLayers(*band->grids.fraction, band->k0, band->k1); });
                  band->grids.fraction.reset();  // the fractions are done with: free them before the band waits
                  return band;
                }) &
            tbb::make_filter<std::shared_ptr<Band>, void>(tbb::filter_mode::serial_in_order, [&](std::shared_ptr<Band> band) {
              emitArena.run([&] { writer->addBand({band->material, band->grids.modulus, band->k0, band->k1}); });
              const int done = band->k1 - kFirst;
              band.reset();
              if (options.onBand) options.onBand(done, layers);
            }));
    if (options.beforeFinalize) options.beforeFinalize(writer->metadata());
    printer_profiles::JobResult result;
    emitArena.run([&] { result = writer->finalize(); });
    account();
    return result;
  } catch (...) {
    account();
    throw;
  }
}

}  // namespace rodfab::slicer
