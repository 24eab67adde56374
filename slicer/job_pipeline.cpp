#include "slicer/job_pipeline.hpp"

#include "slicer/pipeline_lanes.hpp"

#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "common/stopwatch.hpp"

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <stdexcept>
#include <thread>

namespace rodfab::slicer {

namespace {

using Clock = std::chrono::steady_clock;
using common::secondsSince;

using common::processCpuSeconds;

// One stage's own task arena: a thread waiting inside one stage (joining its parallel loops) never
// picks up another stage's tasks, so a band is not held up by work of the stages it overlaps.
// `run` adds the wall time of `f` to `busy`; it is called by one thread at a time (serial filters).
class StageArena {
public:
  explicit StageArena(int concurrency) : arena_(concurrency) {}

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
};

// One band on its way through the stages.
struct Band {
  int k0 = 0, k1 = 0;
  BandGrids grids;
  openvdb::BoolGrid::Ptr material;
};

using BandPtr = std::shared_ptr<Band>;
using detail::Lane;
using detail::LaneStopped;
using Lanes = detail::PipelineLanes<BandPtr>;


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

namespace {

// The bands' lane: makes and dithers every band and hands it to the writer's lane (or, on one thread,
// writes it too), at most kBandsInFlight alive at once. Each stage checks for an interrupt first.
class BandStages {
public:
  BandStages(const BandSource& source, materials::Ditherer& ditherer, const PipelineOptions& options, int threads,
             StageSeconds& seconds)
      : source_(source), ditherer_(ditherer), options_(options), sourceArena_(threads), ditherArena_(threads),
        seconds_(seconds) {}

  BandPtr make(Lanes& lanes, int k0, int kLast) {
    common::throwIfInterrupted();
    auto band = std::make_shared<Band>();
    band->k0 = k0;
    band->k1 = std::min(kLast + 1, bandEnd(k0, options_.bandLayers));
    const bool next = ditherer_.readsNextLayer() && band->k1 <= kLast;
    sourceArena_.run(seconds_.source, [&] {
      lanes.runShared(Lane::bands, [&] { band->grids = source_(band->k0, band->k1, next); });
    });
    common::throwIfInterrupted();
    ditherArena_.run(seconds_.dither, [&] {
      lanes.runShared(Lane::bands, [&] {
        band->material = options_.ditherBand ? options_.ditherBand(band->grids, band->k0, band->k1)
                                             : ditherer_.ditherLayers(*band->grids.fraction, band->k0, band->k1);
      });
    });
    band->grids.fraction.reset();  // the fractions are done with: free them before the band waits
    return band;
  }

private:
  const BandSource& source_;
  materials::Ditherer& ditherer_;
  const PipelineOptions& options_;
  StageArena sourceArena_, ditherArena_;
  StageSeconds& seconds_;
};

// The writer's lane: writes the bands in order.
class WriterStage {
public:
  WriterStage(std::optional<printer_profiles::JobWriter>& writer, const PipelineOptions& options, int threads, int kFirst,
              int layers, StageSeconds& seconds)
      : writer_(writer), options_(options), arena_(threads), kFirst_(kFirst), layers_(layers), seconds_(seconds) {}

  void write(Lanes& lanes, BandPtr band) {
    common::throwIfInterrupted();
    arena_.run(seconds_.emit, [&] {
      lanes.runShared(Lane::writer, [&] {
        writer_->addBand({band->material, band->grids.modulus, band->k0, band->k1});
      });
    });
    const int done = band->k1 - kFirst_;
    band.reset();
    lanes.release();
    if (options_.onBand) options_.onBand(done, layers_);
  }
  // The writer's lane on a thread of its own: every band handed over, until the lanes close or stop.
  void run(Lanes& lanes) {
    try {
      while (BandPtr band = lanes.take()) write(lanes, std::move(band));
    } catch (const LaneStopped&) {
    } catch (...) {
      lanes.stop(std::current_exception());
    }
  }

  StageArena& arena() { return arena_; }

private:
  std::optional<printer_profiles::JobWriter>& writer_;  // made in the writer's arena, then used here
  const PipelineOptions& options_;
  StageArena arena_;
  const int kFirst_, layers_;
  StageSeconds& seconds_;
};

// Every band through the stages: on two lanes when there are two threads or more, else one after
// another on the calling thread.
void streamBands(BandStages& bands, WriterStage& writer, int kFirst, int kLast, int threads) {
  Lanes lanes(kBandsInFlight);
  if (threads < 2) {
    for (int k0 = kFirst; k0 <= kLast;) {
      lanes.reserve();
      BandPtr band = bands.make(lanes, k0, kLast);
      k0 = band->k1;
      writer.write(lanes, std::move(band));
    }
    return;
  }
  // The lanes are two threads of the job's `threads`: TBB's own workers make up the rest.
  const tbb::global_control workers(tbb::global_control::max_allowed_parallelism, std::size_t(threads - 1));
  std::thread writerLane([&] { writer.run(lanes); });
  try {
    for (int k0 = kFirst; k0 <= kLast;) {
      lanes.reserve();
      BandPtr band = bands.make(lanes, k0, kLast);
      k0 = band->k1;
      lanes.handOver(std::move(band));
    }
    lanes.closeAndDrain();
  } catch (const LaneStopped&) {
  } catch (...) {
    lanes.stop(std::current_exception());
  }
  writerLane.join();
  if (std::exception_ptr error = lanes.error()) std::rethrow_exception(error);
}

}  // namespace

printer_profiles::JobResult streamJob(printer_profiles::JobSpec spec, const BandSource& source,
                                      materials::Ditherer& ditherer, const PipelineOptions& options,
                                      StageSeconds& seconds) {
  if (options.bandLayers < 1) throw std::invalid_argument("band size must be at least one layer");
  const openvdb::CoordBBox part = spec.partBounds;
  if (part.empty()) throw std::invalid_argument("the part has no layers to print");
  const int kFirst = part.min().z(), kLast = part.max().z(), layers = kLast - kFirst + 1;

  const auto start = Clock::now();
  const double cpuStart = processCpuSeconds();
  const auto account = [&] {
    seconds.wall += secondsSince(start);
    seconds.cpu += processCpuSeconds() - cpuStart;
  };
  const int threads = stageConcurrency();
  try {
    std::optional<printer_profiles::JobWriter> writer;
    BandStages bands(source, ditherer, options, threads, seconds);
    WriterStage writerStage(writer, options, threads, kFirst, layers, seconds);
    writerStage.arena().run(seconds.emit, [&] { writer.emplace(std::move(spec)); });
    ditherer.reset();
    streamBands(bands, writerStage, kFirst, kLast, threads);
    if (options.beforeFinalize) options.beforeFinalize(writer->metadata());
    printer_profiles::JobResult result;
    writerStage.arena().run(seconds.emit, [&] { result = writer->finalize(); });
    account();
    return result;
  } catch (...) {
    account();
    throw;
  }
}

}  // namespace rodfab::slicer
