// Seconds between two moments of the steady clock (the stage timings commands and reports print), and
// the process's CPU seconds (the figure benchmarks report, as it holds on a loaded machine), and a
// thread's.
#pragma once

#include <sys/resource.h>
#include <time.h>

#include <chrono>

namespace rodfab::common {

// Seconds from `start` to now (std::chrono::steady_clock, so never negative). Thread-safe.
inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// User + system CPU seconds of the whole process so far (every thread, live or ended); 0 if the system
// cannot say. Thread-safe.
inline double processCpuSeconds() {
  rusage usage{};
  if (::getrusage(RUSAGE_SELF, &usage) != 0) return 0.0;
  const auto seconds = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec); };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

// Seconds on a CPU-time clock: CLOCK_THREAD_CPUTIME_ID (the calling thread's), or a clock
// pthread_getcpuclockid gave for another live thread; 0 if the system cannot read it. Thread-safe.
inline double cpuClockSeconds(clockid_t clock) {
  timespec t{};
  if (::clock_gettime(clock, &t) != 0) return 0.0;
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

}  // namespace rodfab::common
