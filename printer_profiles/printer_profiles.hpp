// printer_profiles/: printer profiles and the job emitter. Profiles say what a printer takes (voxel
// size and dpi, tray, materials, image format and naming, support policy); the emitter turns the
// material grid, band by band, into its layer bitmaps, build file, previews and manifest, and
// `inspectJob` re-reads a job and checks all of it.
#pragma once

#include "printer_profiles/bitmap.hpp"
#include "printer_profiles/inspect.hpp"
#include "printer_profiles/job_archive.hpp"
#include "printer_profiles/job_layout.hpp"
#include "printer_profiles/job_writer.hpp"
#include "printer_profiles/profile.hpp"
