// What the commands that write print jobs (slice, coupons) share: the job's output options and the
// way their summaries print counts.
#pragma once

#include "printer_profiles/job_writer.hpp"
#include "slicer/options.hpp"

#include <cstdint>
#include <optional>
#include <string>

namespace rodfab::cli {

// 1234567 -> "1,234,567".
std::string formatCount(std::uint64_t n);

// Fills `out` from --output, --force, --format (zip | dir), --image-format (bmp | png) and, for the
// commands that declare it, --support (printer | explicit). Returns the usage error for a bad value
// (the caller prints it and exits with kUsage), or nullopt.
std::optional<std::string> parseJobOptions(const po::variables_map& vm, printer_profiles::JobOptions& out);

}  // namespace rodfab::cli
