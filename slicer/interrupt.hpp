// SIGINT / SIGTERM as a request to stop: the job polls it between bands, cleans up its temporaries
// and exits with 128 + signal, leaving nothing that looks like a job.
#pragma once

#include <stdexcept>

namespace rodfab::cli {

// Installs the handlers for its lifetime and restores the previous ones afterwards.
class InterruptGuard {
public:
  InterruptGuard();
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

  // The signal received (SIGINT or SIGTERM), or 0.
  static int pending();
};

struct Interrupted : std::runtime_error {
  explicit Interrupted(int signal);
  int signal;
};

// Throws Interrupted when a signal is pending.
void throwIfInterrupted();

}  // namespace rodfab::cli
