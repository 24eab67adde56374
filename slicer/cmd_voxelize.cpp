// rodfab voxelize: a design rasterized into a sparse modulus grid (.vdb) at the printer profile's
// voxel, or at --voxel-size (slicer/voxelize_summary.hpp reports it).
#include "common/interrupt.hpp"
#include "common/stopwatch.hpp"
#include "geometry/geometry.hpp"
#include "slicer/command.hpp"
#include "slicer/options.hpp"
#include "slicer/profile_option.hpp"
#include "common/memory_budget.hpp"
#include "slicer/value_parsers.hpp"
#include "slicer/voxelize_summary.hpp"
#include "voxel/voxel.hpp"

#include <chrono>
#include <filesystem>
#include <optional>
#include <variant>

namespace rodfab::cli {

namespace {

void addVoxelizeOptions(po::options_description& options) {
  options.add_options()
      ("design", po::value<std::string>()->required()->value_name("DESIGN.json"), "design file (rodfab.design/1 JSON)")
      ("output,o", po::value<std::string>()->required()->value_name("GRID.vdb"), "grid file to write (.vdb, grid \"modulus_mpa\")")
      ("voxel-size", po::value<std::string>()->value_name("X,Y,Z"),
       "voxel size X,Y,Z in mm (z = build direction) instead of a printer profile's voxel")
      ("json", "print the statistics as JSON on stdout");
  addThreadsOption(options, "the grid is the same for any count");
  addProfileOptions(options);
}

// --voxel-size when given (nullopt: the profile's voxel); the exit code after a usage error.
std::variant<std::optional<openvdb::Vec3d>, int> voxelSizeOption(const po::variables_map& vm) {
  if (!vm.count("voxel-size")) return std::nullopt;
  if (!vm["profile"].defaulted() || vm.count("print-mode"))
    return usageError("voxelize", "--voxel-size replaces the profile's voxel: give it or --profile/--print-mode, not both");
  try {
    const std::array<double, 3> size = parseVoxelSizeMm("--voxel-size", vm["voxel-size"].as<std::string>());
    return std::optional<openvdb::Vec3d>(openvdb::Vec3d(size[0], size[1], size[2]));
  } catch (const BadValue& e) {
    return usageError("voxelize", e.what());
  }
}

bool gridFile(const std::filesystem::path& p) { return voxel::isGridFile(p.string()); }

}  // namespace

int runVoxelize(const std::vector<std::string>& args) {
  po::variables_map vm;
  if (auto code = parseOptionsWithInput("voxelize", addVoxelizeOptions, "design", args, vm)) return *code;
  auto voxelSizeOrCode = voxelSizeOption(vm);
  if (const int* code = std::get_if<int>(&voxelSizeOrCode)) return *code;
  std::optional<openvdb::Vec3d> voxelSize = std::get<0>(voxelSizeOrCode);
  const std::optional<int> threads = threadCount("voxelize", vm);
  if (!threads) return kUsage;
  const std::string file = vm["design"].as<std::string>(), output = vm["output"].as<std::string>();
  commandLineAccepted();
  const ThreadLimit limit(*threads);
  std::string profileName = "(--voxel-size)";
  if (!voxelSize) {
    int profileFailure = kFailed;
    const std::optional<printer_profiles::Profile> profile = profileFromOptions(vm, "voxelize", "nothing was written", profileFailure);
    if (!profile) return profileFailure;
    voxelSize = profile->voxelSize();
    profileName = profile->name + (profile->printMode.empty() ? "" : " (" + profile->printMode + ")");
  }
  const std::optional<geometry::RodStructure> design = readDesignOrReport(file, "nothing was written");
  if (!design) return kFailed;
  // An existing grid is replaced only when rodfab wrote it.
  if (!outputAllowed(output, {file}, {"grid file", true, "", gridFile})) return kFailed;

  const auto start = std::chrono::steady_clock::now();
  const voxel::PrinterGrid grid = voxel::makePrinterGrid(*design, *voxelSize);
  // The whole grid is held in memory (slice streams bands instead): refuse before the first voxel.
  common::requireMemory(voxel::estimateRasterizationBytes(*design, grid),
                        {.what = "voxelizing " + file + " into one grid in memory",
                         .remedy = "use a coarser --voxel-size, or slice the design (`rodfab slice` streams it in bands)"});
  const voxel::Rasterization ras = voxel::rasterize(*design, grid, {*threads, common::interruptRequested});
  const double seconds = common::secondsSince(start);
  const voxel::GridStatistics s = voxel::computeStatistics(*ras.grid, grid, ras.voxelsPerRod);

  openvdb::MetaMap metadata;
  metadata.insertMeta("rodfab_design", openvdb::StringMetadata(file));
  metadata.insertMeta("rodfab_voxel_size_mm", openvdb::Vec3DMetadata(grid.voxelSize));
  voxel::writeGridFile(output, *ras.grid, metadata);

  const std::size_t empty = warnThinAndEmptyRods(*design, grid, s.voxelsPerRod);
  const VoxelizeSummary summary{file, output, profileName, *design, grid, s, empty, seconds};
  if (vm.count("json")) printVoxelizeJson(summary);
  else printVoxelizeLines(summary);
  return kOk;
}

}  // namespace rodfab::cli
