// A job on disk, as a zip archive or a plain directory: the names every job has, and the three parts
// that handle one: reading its files (job_files.hpp), telling what lies at an output path
// (output_occupant.hpp) and writing the zip (zip_writer.hpp).
#pragma once

#include "printer_profiles/job_files.hpp"
#include "printer_profiles/output_occupant.hpp"
#include "printer_profiles/zip_writer.hpp"

#include <cstddef>

namespace rodfab::printer_profiles {

inline constexpr const char* kJobFormat = "rodfab.job/1";
inline constexpr const char* kManifestName = "manifest.json";
// The job report (slicer/job_report.hpp), named by the manifest's "report" when the job has one.
inline constexpr const char* kReportName = "report.html";
// The largest manifest.json read when telling whether an existing path is a rodfab job: a job of the
// profile maxima (65,536 layers, three bitmaps each) writes under 64 MB.
inline constexpr std::size_t kMaxManifestBytes = std::size_t{128} << 20;

}  // namespace rodfab::printer_profiles
