#include "slicer/command.hpp"

#include "common/interrupt.hpp"
#include "common/local_time_zone.hpp"
#include "common/memory_budget.hpp"

#include <unistd.h>

#include <cstdlib>
#include <exception>
#include <iostream>
#include <new>
#include <string>

namespace {

using namespace rodfab::cli;

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

}  // namespace

int main(int argc, char** argv) {
  rodfab::common::keepLocalTimeZone();
  if (argc < 2) {
    printUsage(std::cerr);
    return kUsage;
  }
  const std::string name = argv[1];
  if (name == "--help" || name == "-h" || name == "help") {
    printUsage(std::cout);
    return kOk;
  }
  if (name == "--version") {
    std::cout << "rodfab " << RODFAB_VERSION << '\n';
    return kOk;
  }
  const Command* command = findCommand(name);
  if (!command) {
    std::cerr << "rodfab: unknown command '" << name << "'\n\n";
    printUsage(std::cerr);
    return kUsage;
  }
  rodfab::common::installInterruptHandlers();
  std::set_terminate(onTerminate);
  rodfab::common::setMemoryBudget(rodfab::common::defaultMemoryBudget());
  rodfab::common::CommandOutputs outputs;  // what the command writes, and what that replaces, until it ends
  return rodfab::common::finishCommand(outputs, runCommand(*command, std::vector<std::string>(argv + 2, argv + argc)));
}
