// Re-reading a job: every checksum, image size, bit depth, DPI and axis orientation, model materials
// never overlapping, support never overlapping the model, the build file against the manifest.
#pragma once

#include "printer_profiles/job_archive.hpp"
#include "printer_profiles/job_writer.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

struct InspectReport {
  std::filesystem::path job;
  std::vector<std::string> defects;  // empty: the job is sound
  nlohmann::json manifest;           // null when it could not be read
  std::size_t filesChecked = 0;
  int width = 0, height = 0, layers = 0;
  std::vector<MaterialTotals> materials;  // counted from the decoded images

  bool ok() const { return defects.empty(); }
};

// Never throws for a damaged job: every problem becomes a defect. A path with the emitter's
// temporary name is refused as unfinished.
InspectReport inspectJob(const std::filesystem::path& job);
// The same checks on an already opened job (the emitter verifies its temporary before renaming it).
InspectReport inspectJobFiles(const JobFiles& files);

}  // namespace rodfab::printer_profiles
