#include "slicer/slice_summary.hpp"

#include <cstdio>
#include <iostream>

namespace rodfab::cli {

namespace {

constexpr int kLabel = 16;  // the label column of the summary lines

std::uint64_t rodsWithoutVoxels(const slicer::SliceReport& report) {
  std::uint64_t n = 0;
  for (std::uint64_t voxels : report.voxelsPerRod) n += voxels == 0;
  return n;
}

void printSliceJson(const SliceSummary& s, const slicer::SliceReport& report) {
  const materials::MappingStats& mapping = report.mapping;
  const slicer::StageSeconds& seconds = report.seconds;
  const std::string& warning = s.calibration->materialsWarning;
  nlohmann::json j = jobJson(report.job, *s.profile);
  j["design"] = s.designFile;
  j["voxels"] = mapping.voxels;
  j["ditherer"] = s.ditherer;
  j["seed"] = s.seed;
  j["calibration"] = {{"file", s.calibration->fileName}, {"sha256", s.calibration->sha256}};
  j["calibration_warning"] = warning.empty() ? nlohmann::json(nullptr) : nlohmann::json(warning);
  j["clamped_moduli"] = {{"below_floor", mapping.clamps.belowFloor}, {"above_max", mapping.clamps.aboveMax},
                         {"floor_mpa", report.floorMpa}, {"max_mpa", report.maxModulusMpa}};
  j["rods_without_voxels"] = rodsWithoutVoxels(report);
  // What the memory check compared with the budget (--max-memory), for the band size chosen.
  j["memory"] = {{"estimate_bytes", report.memoryEstimateBytes}, {"band_layers", report.bandLayers}};
  // Wall times; the stages' busy times overlap inside "bands" (job_pipeline.hpp); CPU of the whole
  // process over the bands.
  j["seconds"] = {{"inputs", s.inputSeconds},
                  {"support", report.supportSeconds},
                  {"bands", seconds.wall},
                  {"total", s.totalSeconds},
                  {"busy", {{"voxelize", seconds.source}, {"dither", seconds.dither}, {"emit", seconds.emit},
                            {"map_in", report.mappedWhileDithering ? "dither" : "voxelize"}}},
                  {"cpu_bands", seconds.cpu},
                  {"cpu", {{"voxelize", seconds.sourceCpu}, {"dither", seconds.ditherCpu}, {"emit", seconds.emitCpu}}}};
  std::cout << j.dump(2) << '\n';
}

void printSliceLines(const SliceSummary& s, const slicer::SliceReport& report, const std::string& format) {
  const materials::MappingStats& mapping = report.mapping;
  const ChosenCalibration& cal = *s.calibration;
  printJobLine(report.job, format, kLabel);
  std::printf("design:         %s (%zu rods)\n", s.designFile.c_str(), s.rods);
  printPrinterLine(*s.profile, kLabel);
  printLayersLine(report.job, *s.profile, kLabel);
  std::printf("voxels:         %s model voxels\n", formatCount(mapping.voxels).c_str());
  printMaterialLines(report.job);
  std::printf("dithering:      %s, seed %llu\n", s.ditherer.c_str(), static_cast<unsigned long long>(s.seed));
  std::printf("calibration:    %s, sha256 %.12s... (floor %.3g MPa = %.1f %% Vero, max %.4g MPa)\n", cal.fileName.c_str(),
              cal.sha256.c_str(), report.floorMpa, 100.0 * report.floorFraction, report.maxModulusMpa);
  if (!cal.materialsWarning.empty()) std::printf("                WARNING: %s\n", cal.materialsWarning.c_str());
  std::printf("clamped moduli: %s below the floor, %s above the stiffest mix\n", formatCount(mapping.clamps.belowFloor).c_str(),
              formatCount(mapping.clamps.aboveMax).c_str());
  const slicer::StageSeconds& t = report.seconds;
  std::printf("time:           %.2f s inputs, %.2f s support, %.2f s bands and job; %.2f s total (wall)\n", s.inputSeconds,
              report.supportSeconds, t.wall, s.totalSeconds);
  const bool mapInDither = report.mappedWhileDithering;
  std::printf("bands:          busy %.2f s voxelize%s, %.2f s %sdither, %.2f s emit (wall, overlapping)\n", t.source,
              mapInDither ? "" : " + map", t.dither, mapInDither ? "map + " : "", t.emit);
  std::printf("CPU:            %.2f s voxelize%s, %.2f s %sdither, %.2f s emit; %.2f s all threads\n", t.sourceCpu,
              mapInDither ? "" : " + map", t.ditherCpu, mapInDither ? "map + " : "", t.emitCpu, t.cpu);
}

}  // namespace

void printSliceSummary(const SliceSummary& s, const slicer::SliceReport& report, const JobCommandOptions& options) {
  if (options.json) printSliceJson(s, report);
  else printSliceLines(s, report, options.format);
  if (!s.calibration->materialsWarning.empty())
    std::cerr << "rodfab slice: warning: " << s.calibration->materialsWarning << '\n';
  for (const std::string& warning : report.warnings) std::cerr << "rodfab slice: warning: " << warning << '\n';
  if (const std::uint64_t empty = rodsWithoutVoxels(report))
    std::cerr << "rodfab slice: warning: " << empty
              << " rod(s) hold no voxel centre (thinner than the voxel or hidden in other rods); rodfab voxelize --json lists them\n";
  if (report.mapping.clamps.total() > 0 && !options.quiet)
    std::cerr << "rodfab slice: note: " << formatCount(report.mapping.clamps.total())
              << " voxel(s) asked for a modulus the materials cannot make; they were clamped (see the summary)\n";
}

}  // namespace rodfab::cli
