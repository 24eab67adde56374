#include "common/interrupt.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace rodfab::common {

namespace fs = std::filesystem;

namespace {

std::atomic<int> pendingSignal{0};
std::atomic<bool> commandFinished{false};  // after finishCommand, signals change nothing
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void onSignal(int signal) {
  if (commandFinished.load(std::memory_order_relaxed)) return;
  int none = 0;
  pendingSignal.compare_exchange_strong(none, signal, std::memory_order_relaxed);
}

// Paths to remove on interrupt. The mutex also makes commits and the watchdog's cleanup exclusive.
std::mutex registryMutex;
std::vector<fs::path>& registry() {
  static std::vector<fs::path>* paths = new std::vector<fs::path>;  // outlives static destruction
  return *paths;
}

void removeRegisteredLocked() {
  for (const fs::path& p : registry()) {
    // Other threads may still be adding files to a folder being removed: try again a few times.
    std::error_code ec;
    for (int attempt = 0; attempt < 5; ++attempt) {
      fs::remove_all(p, ec);
      if (!ec && !fs::exists(fs::symlink_status(p, ec))) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  registry().clear();
}

constexpr auto kGrace = std::chrono::milliseconds(600);
constexpr auto kPoll = std::chrono::milliseconds(20);

void watchdog() {
  for (;;) {
    std::this_thread::sleep_for(kPoll);
    const int signal = pendingSignal.load(std::memory_order_relaxed);
    if (!signal) continue;
    std::this_thread::sleep_for(kGrace);
    std::lock_guard lock(registryMutex);
    if (commandFinished.load()) return;
    removeRegisteredLocked();
    // The same words as Interrupted's message: the user learns the same thing either way.
    const std::string message = std::string("rodfab: interrupted by ") + (signal == SIGTERM ? "SIGTERM" : "SIGINT") +
                                " (the work did not stop within the grace time, so it was cut short); nothing was written\n";
    [[maybe_unused]] const auto written = ::write(STDERR_FILENO, message.data(), message.size());
    ::_exit(128 + signal);
  }
}

}  // namespace

void installInterruptHandlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    struct sigaction action {};
    action.sa_handler = onSignal;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, nullptr);
    sigaction(SIGTERM, &action, nullptr);
    std::thread(watchdog).detach();
  });
}

int interruptRequested() { return pendingSignal.load(std::memory_order_relaxed); }

Interrupted::Interrupted(int s)
    : std::runtime_error(std::string("interrupted by ") + (s == SIGTERM ? "SIGTERM" : "SIGINT") +
                         "; nothing was written"),
      signal(s) {}

void throwIfInterrupted() {
  if (const int s = interruptRequested()) throw Interrupted(s);
}

void registerCleanup(const fs::path& path) {
  std::lock_guard lock(registryMutex);
  auto& r = registry();
  if (std::find(r.begin(), r.end(), path) == r.end()) r.push_back(path);
}

void unregisterCleanup(const fs::path& path) {
  std::lock_guard lock(registryMutex);
  auto& r = registry();
  r.erase(std::remove(r.begin(), r.end(), path), r.end());
}

void commitRegistered(const fs::path& temporary, const fs::path& committed,
                      void (*commit)(const fs::path&, const fs::path&)) {
  std::lock_guard lock(registryMutex);
  if (const int s = interruptRequested()) throw Interrupted(s);
  commit(temporary, committed);
  auto& r = registry();
  r.erase(std::remove(r.begin(), r.end(), temporary), r.end());
  if (std::find(r.begin(), r.end(), committed) == r.end()) r.push_back(committed);
}

namespace {

void blockInterrupts() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
}

}  // namespace

int abandonCommand(int exitCode) {
  blockInterrupts();
  std::lock_guard lock(registryMutex);
  commandFinished.store(true);
  removeRegisteredLocked();
  const int s = interruptRequested();
  return s ? 128 + s : exitCode;
}

int finishCommand(int exitCode) {
  blockInterrupts();
  std::lock_guard lock(registryMutex);
  commandFinished.store(true);
  if (const int s = interruptRequested()) {
    removeRegisteredLocked();
    return 128 + s;
  }
  registry().clear();
  return exitCode;
}

}  // namespace rodfab::common
