#include "slicer/command.hpp"

#include <algorithm>
#include <cstring>
#include <exception>
#include <iostream>

namespace {

using namespace rodfab::cli;

constexpr Command kCommands[] = {
    {"validate", "check a design file and summarize it", runValidate},
    {"slice", "turn a design into a print job: voxelize, map, dither, emit the layer bitmaps", runSlice},
    {"coupons", "make the print job for DMA calibration bars, one per Vero fraction, with the jobs' ditherer", runCoupons},
    {"voxelize", "rasterize a design into a sparse modulus grid (.vdb) at printer resolution", runVoxelize},
    {"calibrate", "fit modulus vs Vero fraction to DMA data; write a calibration file and plot", runCalibrate},
    {"profiles", "list the bundled printer profiles, or show one", runProfiles},
    {"inspect", "re-read a print job and verify every file, size, DPI and orientation", runInspect},
    {"dither-report", "measure each ditherer's quality on uniform blocks and a thin rod", runDitherReport},
    {"simulate", "solve a design's rods under its mechanics loads (Cosserat rods); write the deformed design", runSimulate},
};
// usage() pads command names to 15 columns.
static_assert(std::ranges::all_of(kCommands, [](const Command& c) { return std::char_traits<char>::length(c.name) < 15; }));

void usage(std::ostream& out) {
  out << "rodfab: slicer and print-job driver for 4D-printed multi-material rod structures\n\n"
         "usage: rodfab COMMAND [options]   (rodfab COMMAND --help for the options of one command)\n\ncommands:\n";
  for (const Command& c : kCommands) out << "  " << c.name << std::string(15 - std::strlen(c.name), ' ') << c.summary << '\n';
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    usage(std::cerr);
    return kUsage;
  }
  const std::string name = argv[1];
  if (name == "--help" || name == "-h" || name == "help") {
    usage(std::cout);
    return kOk;
  }
  if (name == "--version") {
    std::cout << "rodfab " << RODFAB_VERSION << '\n';
    return kOk;
  }
  for (const Command& c : kCommands) {
    if (name != c.name) continue;
    try {
      return c.run(std::vector<std::string>(argv + 2, argv + argc));
    } catch (const std::exception& e) {
      std::cerr << "rodfab " << name << ": " << e.what() << '\n';
      return kFailed;
    }
  }
  std::cerr << "rodfab: unknown command '" << name << "'\n\n";
  usage(std::cerr);
  return kUsage;
}
