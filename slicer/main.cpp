#include "slicer/command.hpp"

#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"

#include <algorithm>
#include <cstring>
#include <exception>
#include <iostream>
#include <new>
#include <unistd.h>

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

// Out of memory where an exception cannot travel (a noexcept path, a destructor) still ends with the
// message and without this run's temporaries, not with an abort.
[[noreturn]] void onTerminate() {
  std::string message = "rodfab: internal error: terminated\n";
  if (const std::exception_ptr current = std::current_exception()) {
    try {
      std::rethrow_exception(current);
    } catch (const std::bad_alloc&) {
      message = "rodfab: " + rodfab::common::outOfMemoryMessage() + "\n";
    } catch (const std::exception& e) {
      message = std::string("rodfab: internal error: ") + e.what() + "\n";
    } catch (...) {
    }
  }
  [[maybe_unused]] const auto written = ::write(STDERR_FILENO, message.data(), message.size());
  std::_Exit(rodfab::common::abandonCommand(kFailed));
}

// Runs one command; every failure becomes an exit code and one message.
int runCommand(const Command& c, const std::vector<std::string>& args) {
  try {
    return c.run(args);
  } catch (const rodfab::common::Interrupted& e) {
    std::cerr << "rodfab " << c.name << ": " << e.what() << '\n';
    return 128 + e.signal;
  } catch (const std::bad_alloc&) {
    std::cerr << "rodfab " << c.name << ": " << rodfab::common::outOfMemoryMessage() << '\n';
    return kFailed;
  } catch (const std::exception& e) {
    std::cerr << "rodfab " << c.name << ": " << e.what() << '\n';
    return kFailed;
  }
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
    rodfab::common::installInterruptHandlers();
    std::set_terminate(onTerminate);
    rodfab::common::setMemoryBudget(rodfab::common::defaultMemoryBudget());
    return rodfab::common::finishCommand(runCommand(c, std::vector<std::string>(argv + 2, argv + argc)));
  }
  std::cerr << "rodfab: unknown command '" << name << "'\n\n";
  usage(std::cerr);
  return kUsage;
}
