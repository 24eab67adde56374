// Seconds between two moments of the steady clock: the stage timings commands and reports print.
#pragma once

#include <chrono>

namespace rodfab::common {

// Seconds from `start` to now (std::chrono::steady_clock, so never negative). Thread-safe.
inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace rodfab::common
