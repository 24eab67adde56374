#include "slicer/command.hpp"

#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "voxel/rasterize.hpp"

#include <algorithm>
#include <cstring>
#include <iostream>
#include <new>

namespace rodfab::cli {

namespace {

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
    {"optimize", "find each rod's E(s) that trains the design into its load cases' target shapes", runOptimize},
    {"rods-from-mesh", "turn a triangle mesh into rods: the dual of the simplified mesh, laid on its surface", runRodsFromMesh},
    {"rods-from-cad", "turn the edge curves of a STEP or IGES model into rods with their exact NURBS", runRodsFromCad},
};
// printUsage() pads command names to 15 columns.
static_assert(std::ranges::all_of(kCommands, [](const Command& c) { return std::char_traits<char>::length(c.name) < 15; }));

}  // namespace

std::span<const Command> commands() { return kCommands; }

const Command* findCommand(const std::string& name) {
  for (const Command& c : kCommands)
    if (name == c.name) return &c;
  return nullptr;
}

void printUsage(std::ostream& out) {
  out << "rodfab: slicer and print-job driver for 4D-printed multi-material rod structures\n\n"
         "usage: rodfab COMMAND [options]   (rodfab COMMAND --help for the options of one command)\n\ncommands:\n";
  for (const Command& c : kCommands) out << "  " << c.name << std::string(15 - std::strlen(c.name), ' ') << c.summary << '\n';
}

int runCommand(const Command& c, const std::vector<std::string>& args) {
  try {
    return c.run(args);
  } catch (const common::Interrupted& e) {
    std::cerr << "rodfab " << c.name << ": " << e.what() << '\n';
    return 128 + e.signal;
  } catch (const voxel::Interrupted&) {
    const int signal = common::interruptRequested();
    std::cerr << "rodfab " << c.name << ": " << common::Interrupted(signal).what() << '\n';
    return 128 + signal;
  } catch (const std::bad_alloc&) {
    std::cerr << "rodfab " << c.name << ": " << common::outOfMemoryMessage() << '\n';
    return kFailed;
  } catch (const std::exception& e) {
    std::cerr << "rodfab " << c.name << ": " << e.what() << '\n';
    return kFailed;
  }
}

}  // namespace rodfab::cli
