// rodfab dither-report: every ditherer's quality (bias, low-pass error, clustering, runs, speed) on
// uniform blocks and a thin rod made at the profile's voxel (slicer/dither_report.hpp measures and
// prints; materials/dither_quality.hpp defines the figures).
#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "materials/materials.hpp"
#include "slicer/command.hpp"
#include "slicer/dither_report.hpp"
#include "slicer/options.hpp"
#include "slicer/profile_option.hpp"
#include "slicer/value_parsers.hpp"

#include <iostream>

namespace rodfab::cli {

namespace {

// Block sides beyond this are not a dither measurement any more (and would leave OpenVDB's index range).
constexpr int kMaxBlockSide = 1 << 16;
// More uniform blocks than this are not a report any more (the memory estimate bounds them too).
constexpr std::size_t kMaxBlocks = 1000;

int usageError(const std::string& what) { return cli::usageError("dither-report", what); }

void addDitherReportOptions(po::options_description& options) {
  options.add_options()
      ("dither", po::value<std::string>()->default_value("all")->value_name("white|blue|error-diffusion|all"), "white, blue, error-diffusion or all")
      ("seed", po::value<Seed>()->default_value(Seed{1})->value_name("N"), "dithering seed")
      ("block", po::value<std::string>()->default_value("128x64x180")->value_name("XxYxZ"), "uniform block size XxYxZ in voxels")
      ("fractions", po::value<std::string>()->default_value("0.1,0.2,...,0.9")->value_name("A,B,...,Z"),
       "Vero fractions of the uniform blocks, comma-separated; A,B,...,Z continues the step B - A up to Z")
      ("rod-diameter", po::value<double>()->default_value(1.0)->value_name("MM"), "rod diameter in mm")
      ("rod-length", po::value<double>()->default_value(10.0)->value_name("MM"), "rod length in mm")
      ("rod-axis", po::value<char>()->default_value('x')->value_name("x|y|z"), "rod direction: x, y or z")
      ("rod-fraction", po::value<float>()->default_value(0.3f, "0.3")->value_name("F"), "Vero fraction of the rod")
      ("mask", po::value<std::string>()->value_name("MASK.rfbn"), "blue-noise mask file (default: the bundled one)")
      ("json", "print the report as JSON on stdout");
  addProfileOptions(options);
}

// The request from a parsed command line; nullopt after a usage error.
std::optional<DitherReportRequest> readRequest(const po::variables_map& vm) {
  DitherReportRequest r;
  const std::string chosen = vm.count("ditherer") ? vm["ditherer"].as<std::string>() : vm["dither"].as<std::string>();
  const std::optional<std::vector<std::string>> methods = ditherMethods(chosen);
  if (!methods) return usageError("--dither: unknown ditherer '" + chosen + "', expected white, blue, error-diffusion or all"), std::nullopt;
  r.methods = *methods;
  try {
    for (double f : parseFractionList("--fractions", vm["fractions"].as<std::string>(), kMaxBlocks))
      r.fractions.push_back(static_cast<float>(f));
    const std::array<int, 3> sides = parseSizeVoxels("--block", vm["block"].as<std::string>(), kMaxBlockSide);
    r.block = openvdb::Coord(sides[0], sides[1], sides[2]);
  } catch (const BadValue& e) {
    return usageError(e.what()), std::nullopt;
  }
  r.axis = vm["rod-axis"].as<char>();
  if (r.axis < 'x' || r.axis > 'z') return usageError("--rod-axis: expected x, y or z"), std::nullopt;
  const std::optional<double> diameter = realOption("dither-report", vm, "rod-diameter", 1e-3, 1e3, "mm");
  const std::optional<double> length = realOption("dither-report", vm, "rod-length", 1e-3, 1e4, "mm");
  if (!diameter || !length) return std::nullopt;
  r.diameterMm = *diameter, r.lengthMm = *length;
  r.rodFraction = vm["rod-fraction"].as<float>();
  if (!(r.rodFraction >= 0.0f && r.rodFraction <= 1.0f)) return usageError("--rod-fraction: expected a number in [0, 1]"), std::nullopt;
  r.json = vm.count("json") > 0;
  return r;
}

}  // namespace

int runDitherReport(const std::vector<std::string>& args) {
  po::options_description options("options"), hidden;
  addDitherReportOptions(options);
  hidden.add_options()("ditherer", po::value<std::string>(), "the old spelling of --dither");
  po::variables_map vm;
  if (auto code = parseOptions("dither-report", options, {}, args, vm, &hidden)) return *code;
  const std::optional<DitherReportRequest> request = readRequest(vm);
  if (!request) return kUsage;
  commandLineAccepted();
  // The regions are made at the printer's voxel: the profile's, the only source of it.
  int profileFailure = kFailed;
  const std::optional<printer_profiles::Profile> profile = profileFromOptions(vm, "dither-report", "no report was made", profileFailure);
  if (!profile) return profileFailure;
  const openvdb::Vec3d voxel = profile->voxelSize();
  common::requireMemory(ditherReportBytes(*request, voxel),
                        {.what = "dither-report's " + std::to_string(request->fractions.size()) + " blocks and rod",
                         .remedy = "use a smaller --block, fewer --fractions or a shorter --rod-length"});
  materials::DitherOptions ditherOptions;
  ditherOptions.seed = vm["seed"].as<Seed>().value;
  ditherOptions.checkInterrupt = [] { common::throwIfInterrupted(); };  // within a leaf's or a layer's work of a signal
  if (vm.count("mask")) {
    try {
      ditherOptions.mask = std::make_shared<const materials::BlueNoiseMask>(materials::BlueNoiseMask::load(vm["mask"].as<std::string>()));
    } catch (const std::exception& e) {
      std::cerr << e.what() << '\n';
      return kFailed;
    }
  }
  printDitherReport(*request, voxel, ditherOptions);
  return kOk;
}

}  // namespace rodfab::cli
