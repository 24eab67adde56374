// The job pipeline: a part's layers, band by band, from Vero fractions through a ditherer into the
// job writer. The source of the fractions is the caller's (a rasterized design for `rodfab slice`,
// uniform bars for `rodfab coupons`); the pipeline keeps one band in flight while the writer encodes
// the previous one, so memory holds two bands, not the part.
#pragma once

#include "materials/ditherer.hpp"
#include "printer_profiles/job_writer.hpp"

#include <openvdb/openvdb.h>

#include <functional>
#include <string>

namespace rodfab::slicer {

// Layers [k0, k1) of the part (plus layer k1 when the pipeline asks for it: error diffusion reads it).
struct BandGrids {
  openvdb::FloatGrid::Ptr fraction;  // "vero_fraction", in the printer grid
  openvdb::FloatGrid::Ptr modulus;   // "modulus_mpa" for the modulus previews; may be null
};
// (k0, k1, withNextLayer) -> the band. Its voxels must lie in the part bounds given to the writer.
using BandSource = std::function<BandGrids(int k0, int k1, bool withNextLayer)>;

struct StageSeconds {
  double source = 0.0;   // building the bands' fractions (rasterization and mapping for slice)
  double dither = 0.0;
  double emit = 0.0;     // waiting for the writer's encoding, and finalize (manifest, zip, verification)
};

struct PipelineOptions {
  int bandLayers = 64;
  // Called after every band with (layers done, layers in the part). May throw to abort (interrupts):
  // the writer then removes everything it staged.
  std::function<void(int, int)> onBand;
  // Called after the last band, before the manifest is written: fill in what the bands counted.
  std::function<void(printer_profiles::JobMetadata&)> beforeFinalize;
};

// Streams every layer of `spec.partBounds` through `source`, `ditherer` and a JobWriter, then
// finalizes the job. Adds the time spent per stage to `seconds`.
printer_profiles::JobResult streamJob(printer_profiles::JobSpec spec, const BandSource& source,
                                      materials::Ditherer& ditherer, const PipelineOptions& options,
                                      StageSeconds& seconds);

}  // namespace rodfab::slicer
