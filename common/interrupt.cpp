#include "common/interrupt.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace rodfab::common {

namespace fs = std::filesystem;

fs::path previousVersionName(const fs::path& file, long pid, int n) {
  std::string hidden = ".";  // appended piecewise: GCC 12 warns falsely (-Wrestrict) on "." + string
  hidden.append(file.filename().string()).append(".rodfab-old-").append(std::to_string(pid));
  hidden.append("-").append(std::to_string(n));
  return file.parent_path() / hidden;
}

namespace {

std::atomic<int> pendingSignal{0};
std::atomic<bool> commandFinished{false};  // after finishCommand, signals change nothing
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void onSignal(int signal) {
  if (commandFinished.load(std::memory_order_relaxed)) return;
  int none = 0;
  pendingSignal.compare_exchange_strong(none, signal, std::memory_order_relaxed);
}

// Paths to remove on interrupt, each with the hidden copy of what it replaced (empty when it replaced
// nothing), put back in its place. The mutex also makes commits and the watchdog's cleanup exclusive.
struct Registered {
  fs::path path, previous;
};
std::mutex registryMutex;
std::vector<Registered>& registry() {
  static std::vector<Registered>* paths = new std::vector<Registered>;  // outlives static destruction
  return *paths;
}

auto findRegistered(const fs::path& path) {
  return std::find_if(registry().begin(), registry().end(), [&](const Registered& r) { return r.path == path; });
}

void removeAndRestore(const Registered& r) {
  // Other threads may still be adding files to a folder being removed: try again a few times.
  std::error_code ec;
  for (int attempt = 0; attempt < 5; ++attempt) {
    fs::remove_all(r.path, ec);
    if (!ec && !fs::exists(fs::symlink_status(r.path, ec))) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (!r.previous.empty()) fs::rename(r.previous, r.path, ec);
}

void removeRegisteredLocked() {
  for (const Registered& r : registry()) removeAndRestore(r);
  registry().clear();
}

// The command is done with its outputs: the files (or job folders) they replaced go for good.
void forgetRegisteredLocked() {
  std::error_code ignored;
  for (const Registered& r : registry())
    if (!r.previous.empty()) fs::remove_all(r.previous, ignored);
  registry().clear();
}

// Live CommandOutputs objects (0 or 1), under registryMutex.
int owners = 0;

// This process's next hidden name beside `file` for the file a commit replaces.
fs::path nextPreviousVersionName(const fs::path& file) {
  static std::atomic<int> counter{0};
  return previousVersionName(file, ::getpid(), counter++);
}

// Keeps the regular file at `file` (one a commit is about to replace) under a hidden name beside it: a
// second hard link, so the commit's rename still replaces the name in one step; on a file system
// without hard links (FAT, as on a printer's USB stick) the file itself, renamed aside. Empty when
// there is no such file; throws when it cannot be kept (then nothing is replaced).
fs::path keepPreviousVersion(const fs::path& file) {
  struct stat st {};
  if (::lstat(file.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return {};
  const fs::path kept = nextPreviousVersionName(file);
  if (::link(file.c_str(), kept.c_str()) != 0 && ::rename(file.c_str(), kept.c_str()) != 0)
    throw std::runtime_error(file.string() + ": cannot keep the file it replaces until the command ends (" + std::strerror(errno) +
                             "); nothing was replaced");
  return kept;
}

// After a failed commit: the kept file back under its name when the commit left none there (it was
// renamed aside), else the hidden link removed.
void restorePreviousVersion(const fs::path& kept, const fs::path& file) {
  if (kept.empty()) return;
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(file, ec))) fs::rename(kept, file, ec);
  else fs::remove(kept, ec);
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
  if (findRegistered(path) == registry().end()) registry().push_back({path, {}});
}

void unregisterCleanup(const fs::path& path) {
  std::lock_guard lock(registryMutex);
  auto& r = registry();
  r.erase(std::remove_if(r.begin(), r.end(), [&](const Registered& e) { return e.path == path; }), r.end());
}

void commitRegistered(const fs::path& temporary, const fs::path& committed,
                      void (*commit)(const fs::path&, const fs::path&)) {
  std::lock_guard lock(registryMutex);
  if (const int s = interruptRequested()) throw Interrupted(s);
  auto& r = registry();
  if (owners == 0) {  // nobody to keep a copy for, nor to take the output back: a plain commit
    commit(temporary, committed);
    r.erase(std::remove_if(r.begin(), r.end(), [&](const Registered& e) { return e.path == temporary; }), r.end());
    return;
  }
  const bool replacesOwnOutput = findRegistered(committed) != registry().end();
  const fs::path previous = replacesOwnOutput ? fs::path() : keepPreviousVersion(committed);
  try {
    commit(temporary, committed);
  } catch (...) {
    restorePreviousVersion(previous, committed);
    throw;
  }
  r.erase(std::remove_if(r.begin(), r.end(), [&](const Registered& e) { return e.path == temporary; }), r.end());
  if (!replacesOwnOutput) r.push_back({committed, previous});
}

bool keepCommitted(const fs::path& committed, const fs::path& replaced) {
  std::lock_guard lock(registryMutex);
  if (owners == 0) return false;
  fs::path kept;
  if (!replaced.empty()) {
    kept = nextPreviousVersionName(committed);
    // Beside the output, on its file system (the writer's staging folder is beside it too).
    if (::rename(replaced.c_str(), kept.c_str()) != 0)
      throw std::runtime_error(committed.string() + ": cannot keep what it replaced until the command ends (" + std::strerror(errno) + ")");
  }
  const auto found = findRegistered(committed);
  if (found == registry().end()) registry().push_back({committed, kept});
  else if (!kept.empty()) found->previous = kept;  // registered bare before (registerCleanup): now with its copy
  return true;
}

void withdrawCommitted(const fs::path& committed) {
  std::lock_guard lock(registryMutex);
  const auto found = findRegistered(committed);
  if (found == registry().end()) return;
  removeAndRestore(*found);
  registry().erase(found);
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

CommandOutputs::CommandOutputs() {
  std::lock_guard lock(registryMutex);
  if (owners > 0) throw std::logic_error("CommandOutputs: one command's outputs are owned already");
  ++owners;
}

CommandOutputs::~CommandOutputs() {
  std::lock_guard lock(registryMutex);
  settleLocked(1);
}

int CommandOutputs::finish(int exitCode) {
  std::lock_guard lock(registryMutex);
  return settleLocked(exitCode);
}

int CommandOutputs::settleLocked(int exitCode) {
  if (finished_) return exitCode;
  finished_ = true;
  --owners;
  if (const int s = interruptRequested()) {
    removeRegisteredLocked();
    return 128 + s;
  }
  if (exitCode == 0) forgetRegisteredLocked();
  else removeRegisteredLocked();  // a failed command: all or none, and what was there before is back
  return exitCode;
}

int finishCommand(CommandOutputs& outputs, int exitCode) {
  blockInterrupts();
  std::lock_guard lock(registryMutex);
  commandFinished.store(true);
  return outputs.settleLocked(exitCode);
}

}  // namespace rodfab::common
