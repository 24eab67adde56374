#include "slicer/job_pipeline.hpp"

#include "common/stopwatch.hpp"

#include <algorithm>
#include <chrono>
#include <stdexcept>

namespace rodfab::slicer {

namespace {

using Clock = std::chrono::steady_clock;
using common::secondsSince;

}  // namespace

printer_profiles::JobResult streamJob(printer_profiles::JobSpec spec, const BandSource& source,
                                      materials::Ditherer& ditherer, const PipelineOptions& options,
                                      StageSeconds& seconds) {
  if (options.bandLayers < 1) throw std::invalid_argument("band size must be at least one layer");
  const openvdb::CoordBBox part = spec.partBounds;
  if (part.empty()) throw std::invalid_argument("the part has no layers to print");
  const bool readsNextLayer = ditherer.name() == "error-diffusion";
  const int kFirst = part.min().z(), kLast = part.max().z(), layers = kLast - kFirst + 1;

  auto start = Clock::now();
  printer_profiles::JobWriter writer(std::move(spec));
  seconds.emit += secondsSince(start);
  ditherer.reset();
  for (int k0 = kFirst; k0 <= kLast; k0 += options.bandLayers) {
    const int k1 = std::min(kLast + 1, k0 + options.bandLayers);
    start = Clock::now();
    BandGrids band = source(k0, k1, readsNextLayer && k1 <= kLast);
    seconds.source += secondsSince(start);

    start = Clock::now();
    openvdb::BoolGrid::Ptr material = ditherer.ditherLayers(*band.fraction, k0, k1);
    seconds.dither += secondsSince(start);

    start = Clock::now();
    writer.addBand({material, band.modulus, k0, k1});  // waits for the previous band's encoding only
    seconds.emit += secondsSince(start);
    if (options.onBand) options.onBand(k1 - kFirst, layers);
  }
  if (options.beforeFinalize) options.beforeFinalize(writer.metadata());
  start = Clock::now();
  printer_profiles::JobResult result = writer.finalize();
  seconds.emit += secondsSince(start);
  return result;
}

}  // namespace rodfab::slicer
