// SIGINT / SIGTERM as a request to stop, for the whole process.
//
// The promise of every rodfab command: interrupted at any moment, it exits with 128 + signal
// (130 / 143) and leaves nothing it wrote behind. Two mechanisms keep it:
//  - cooperative: long work polls `interruptRequested()` (or calls `throwIfInterrupted()`) at least
//    every ~50 ms of work, unwinds, and its owners remove their temporaries;
//  - a watchdog: if the process is still running 0.6 s after the signal, it removes every path in
//    the cleanup registry (below) and ends the process with _exit(128 + signal).
// Outputs that are complete stay registered until the command has returned (`finishCommand`), so a
// signal that lands after a job is committed still removes it: a command either finishes with
// exit 0 or leaves nothing.
//
// Thread safety: every function may be called from any thread. The handlers only store the signal.
#pragma once

#include <filesystem>
#include <stdexcept>

namespace rodfab::common {

// Installs the handlers and starts the watchdog for the life of the process (idempotent).
void installInterruptHandlers();

// The signal received (SIGINT or SIGTERM), or 0.
int interruptRequested();

struct Interrupted : std::runtime_error {
  explicit Interrupted(int signal);
  int signal;
};

// Throws Interrupted when a signal is pending.
void throwIfInterrupted();

// The cleanup registry: paths this process created (temporaries, and outputs it has committed but
// not yet reported). Removed (recursively) when the process is interrupted, and a file a commit
// replaced put back in its place (see commitRegistered). Registering a path that is already
// registered does nothing.
void registerCleanup(const std::filesystem::path& path);
void unregisterCleanup(const std::filesystem::path& path);

// Runs `commit` (typically a rename of a finished temporary onto its final name) while the
// watchdog cannot act, after checking for a pending signal (throws Interrupted without running it).
// After a successful commit `temporary` is unregistered and `committed` registered, so a signal
// before the command returns still removes it. A regular file the commit replaces is kept until then
// (a second hard link, `.NAME.rodfab-old-PID-N` beside it) and put back if the output is removed: an
// interrupted or failed command leaves what was there before, not nothing. Throws std::runtime_error
// (nothing replaced) when that link cannot be made.
void commitRegistered(const std::filesystem::path& temporary, const std::filesystem::path& committed,
                      void (*commit)(const std::filesystem::path&, const std::filesystem::path&));

// Takes back an output committed through commitRegistered (a command whose later outputs failed: all
// or none): removed, and the file it replaced put back. Does nothing for a path not registered.
void withdrawCommitted(const std::filesystem::path& committed);

// Called by main with the command's exit code: blocks further signals, and if one is pending
// removes every registered path (putting back what commits replaced) and returns 128 + signal;
// otherwise removes the kept files commits replaced, forgets the registry (what is registered now is
// the command's output) and returns `exitCode`.
int finishCommand(int exitCode);

// For a command that cannot go on (std::terminate): blocks signals, removes every registered path
// and returns 128 + signal when one is pending, else `exitCode`.
int abandonCommand(int exitCode);

}  // namespace rodfab::common
