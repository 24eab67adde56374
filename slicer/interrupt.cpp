#include "slicer/interrupt.hpp"

#include <atomic>
#include <csignal>
#include <string>

namespace rodfab::cli {

namespace {

std::atomic<int> pendingSignal{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void onSignal(int signal) { pendingSignal.store(signal, std::memory_order_relaxed); }

struct sigaction previousInt, previousTerm;

}  // namespace

InterruptGuard::InterruptGuard() {
  pendingSignal.store(0);
  struct sigaction action {};
  action.sa_handler = onSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, &previousInt);
  sigaction(SIGTERM, &action, &previousTerm);
}

InterruptGuard::~InterruptGuard() {
  sigaction(SIGINT, &previousInt, nullptr);
  sigaction(SIGTERM, &previousTerm, nullptr);
}

int InterruptGuard::pending() { return pendingSignal.load(std::memory_order_relaxed); }

Interrupted::Interrupted(int s)
    : std::runtime_error(std::string("interrupted by ") + (s == SIGTERM ? "SIGTERM" : "SIGINT") +
                         "; no job was written"),
      signal(s) {}

void throwIfInterrupted() {
  if (const int s = InterruptGuard::pending()) throw Interrupted(s);
}

}  // namespace rodfab::cli
