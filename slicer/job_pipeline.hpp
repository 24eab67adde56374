// The job pipeline: a part's layers, band by band, from Vero fractions through a ditherer into the
// job writer. The source of the fractions is the caller's (a rasterized design for `rodfab slice`,
// uniform bars for `rodfab coupons`). The three stages overlap with two bands in flight: while the
// writer encodes band n, band n + 1 is built by the source or dithered, so memory holds at most two
// bands, never the part.
#pragma once

#include "materials/ditherer.hpp"
#include "printer_profiles/job_writer.hpp"

#include <openvdb/openvdb.h>

#include <functional>
#include <string>

namespace rodfab::slicer {

// Layers [k0, k1) of the part (plus layer k1 when the pipeline asks for it: error diffusion reads it).
struct BandGrids {
  openvdb::FloatGrid::Ptr fraction;  // "vero_fraction", in the printer grid; null when PipelineOptions::
                                     // ditherBand makes the material from the moduli
  openvdb::FloatGrid::Ptr modulus;   // "modulus_mpa" for the modulus previews; may be null
};
// (k0, k1, withNextLayer) -> the band. Its voxels must lie in the part bounds given to the writer.
// Called for consecutive bands in increasing k, one call at a time (never concurrently), but on any
// thread and while the ditherer and the writer work on earlier bands.
using BandSource = std::function<BandGrids(int k0, int k1, bool withNextLayer)>;

// Where the pipeline's time went. Wall seconds, except the CPU times. The stages run at the same time, so
// each stage's busy time counts only its own calls (from the start of its work on a band to the end,
// whatever the other stages did meanwhile): each is at most `wall`, and together they exceed it by
// as much as the stages overlapped. `cpu` is the process's user + system time over `wall`, every
// thread included (TBB workers, threads a stage starts itself), so no stage is missed or counted twice.
struct StageSeconds {
  double source = 0.0;   // busy building the bands' fractions (rasterization and mapping for slice)
  double dither = 0.0;   // busy dithering
  double emit = 0.0;     // busy in the writer: its start, the bands (bitmaps, images, compression,
                         // previews) and finalize (manifest, zip, verification)
  double wall = 0.0;     // from the writer's start to the job in place
  double cpu = 0.0;      // process CPU time (user + system, all threads) over `wall`
  // CPU time (user + system) of the threads while inside each stage's own TBB arena: the stage's work on
  // every thread it ran on, and its threads' waiting for more (TBB's workers spin briefly before they
  // leave an arena). Not counted: threads a stage starts outside TBB, and work it runs in a task arena of
  // its own making (the rasterizer and the writer's verification run on the stage's arena unless told
  // to use fewer threads than it has). Each is at most `cpu`.
  double sourceCpu = 0.0, ditherCpu = 0.0, emitCpu = 0.0;
};

// Layers in one leaf of OpenVDB's float and bool trees: a band's grids hold whole 8-layer slabs of
// leaves, so a band of 1 layer costs as much memory as a band of 8.
inline constexpr int kLeafLayers = 8;

// The end (exclusive) of the band streamJob cuts starting at layer k0, for bands of `bandLayers` (> 0)
// layers: a multiple of kLeafLayers ends on a slab boundary (the first band is shorter when the part
// does not start on one); a size dividing kLeafLayers (1, 2, 4) ends on its next multiple, so no band
// crosses a slab boundary or holds leaves of two slabs; other sizes end at k0 + bandLayers. Thread-safe,
// throws nothing.
int bandEnd(int k0, int bandLayers);

// Bands alive at once in streamJob: while the writer encodes one, the next is made or dithered. Memory
// estimates of the jobs it writes count this many (sliceMemoryBytes, couponJobBytes).
inline constexpr int kBandsInFlight = 2;

// Threads each of streamJob's stage arenas runs: the calling thread's arena concurrency, at most the
// thread limit in force (tbb::global_control's max_allowed_parallelism, which cli::ThreadLimit sets for
// --threads; a task_arena's own concurrency does not follow it, so error diffusion took 2 workers' buffers
// at --threads 1), at least 1. Memory estimates of the stages read this too, so they size what the
// stages will hold (sliceMemoryBytes: error diffusion's workers). Call it where streamJob will be called,
// under the same limit. Thread-safe.
int stageConcurrency();

// Bytes the job writer holds for a job of `profile` and `partBounds` with `contactSheetLayers`
// (JobOptions) besides the bands' grids: its layer images and encoders (~30 bytes per pixel of a layer
// image, measured), the previews' views and contact tiles (printer_profiles::previewMemoryBytes, worked
// out from the job's geometry), plus 96 MiB for the process itself (libraries, thread stacks, the
// allocator's arenas: `rodfab slice` of a 2,448-voxel design peaks at 85 MB resident). The fixed share a
// job needs however small its part: ~102 MB on the Connex3. Throws printer_profiles::TrayFitError for
// a part the tray cannot hold and std::invalid_argument for an empty one (printer_profiles::planJob).
// Thread-safe (pure).
std::uint64_t jobWriterBytes(const printer_profiles::Profile& profile, const openvdb::CoordBBox& partBounds,
                             int contactSheetLayers);

struct PipelineOptions {
  // Layers per band, cut as bandEnd says: a multiple of kLeafLayers, or a size dividing it, makes the
  // bands' leaves never shared with the next band's.
  int bandLayers = 64;
  // Called after every band is written with (layers done, layers in the part), on the thread that
  // called streamJob or a TBB worker, never concurrently. May throw to abort: the pipeline stops
  // (the other stages finish the band they are on, start no other), and the writer removes
  // everything it staged.
  std::function<void(int, int)> onBand;
  // Called after the last band, before the manifest is written: fill in what the bands counted.
  std::function<void(printer_profiles::JobMetadata&)> beforeFinalize;
  // The dither stage's work when set: (the source's band, k0, k1) -> the band's material grid, called
  // in the dither stage's arena, one band at a time in increasing k (sliceDesign maps the moduli as it
  // dithers: materials::Ditherer::mapAndDitherLayers, the source leaving `fraction` null). Unset:
  // ditherer.ditherLayers(*fraction, k0, k1). What it throws stops the pipeline as a stage's error does.
  std::function<openvdb::BoolGrid::Ptr(const BandGrids&, int k0, int k1)> ditherBand;
};

// Streams every layer of `spec.partBounds` through `source`, `ditherer` and a JobWriter, then
// finalizes the job. Adds the time spent to `seconds`. The job's bytes do not depend on the thread
// count or the band size. Interrupts (common/interrupt.hpp): every stage checks for a pending signal
// before each band and throws common::Interrupted, so the pipeline stops within one band's work of a
// stage (the rasterizer and the writer's finalize also check as they go); nothing is left staged.
printer_profiles::JobResult streamJob(printer_profiles::JobSpec spec, const BandSource& source,
                                      materials::Ditherer& ditherer, const PipelineOptions& options,
                                      StageSeconds& seconds);

}  // namespace rodfab::slicer
