// Transitional names for the commands written before common/interrupt.hpp: the handlers are now
// installed once for the whole process (main), so InterruptGuard only marks where a command polls.
#pragma once

#include "common/interrupt.hpp"

namespace rodfab::cli {

using common::Interrupted;
using common::throwIfInterrupted;

struct InterruptGuard {
  InterruptGuard() { common::installInterruptHandlers(); }
  static int pending() { return common::interruptRequested(); }
};

}  // namespace rodfab::cli
