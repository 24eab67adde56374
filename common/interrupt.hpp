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
// Who owns the outputs: a CommandOutputs object (below), held by main() for the command it runs and
// by any library user that writes through AtomicOutput or the job writer. While one lives, a commit
// keeps what it replaces (`.NAME.rodfab-old-PID-N`) until the owner ends: removed when it ends in
// success, put back (and the new output removed) when it ends in failure or on a signal. Without
// one, a commit replaces outright and keeps nothing, so nothing is left beside the outputs of a
// program that never calls finishCommand.
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

// The owner of one command's outputs (see the top of this file). At most one lives at a time (a
// second throws std::logic_error); it covers every commit made while it lives, from any thread.
class CommandOutputs {
public:
  CommandOutputs();
  // Without finish() (an exception passing through): the command failed, as finish(1) says.
  ~CommandOutputs();
  CommandOutputs(const CommandOutputs&) = delete;
  CommandOutputs& operator=(const CommandOutputs&) = delete;
  // Ends the command: with a signal pending, removes every registered path, puts back what commits
  // replaced and returns 128 + signal; else with `exitCode` 0 removes the kept copies and forgets the
  // registry (the outputs stay); else (failure) removes the outputs committed, puts back what they
  // replaced (all or none) and returns `exitCode`. Only the first call acts.
  int finish(int exitCode);

private:
  friend int finishCommand(CommandOutputs&, int);
  int settleLocked(int exitCode);
  bool finished_ = false;
};

// Runs `commit` (typically a rename of a finished temporary onto its final name) while the
// watchdog cannot act, after checking for a pending signal (throws Interrupted without running it).
// Without a live CommandOutputs that is all (`temporary` unregistered). With one, after a successful
// commit `temporary` is unregistered and `committed` registered, so a signal before the command
// returns still removes it, and a regular file the commit replaces is kept until then (a second hard
// link, `.NAME.rodfab-old-PID-N` beside it) and put back if the output is removed: an interrupted or
// failed command leaves what was there before, not nothing. Throws std::runtime_error (nothing
// replaced) when that link cannot be made.
void commitRegistered(const std::filesystem::path& temporary, const std::filesystem::path& committed,
                      void (*commit)(const std::filesystem::path&, const std::filesystem::path&));

// For an output committed by other means (a job, zip or folder, exchanged with the job it replaces):
// registers `committed` as commitRegistered does, and moves `replaced` (where the commit put what it
// replaced; empty when it replaced nothing) beside it as `.NAME.rodfab-old-PID-N`, kept until the
// command ends and put back if the output is removed. Returns false and does nothing without a live
// CommandOutputs (the caller disposes of `replaced`). Throws std::runtime_error, `replaced` left
// where it was and nothing registered, when it cannot be moved.
bool keepCommitted(const std::filesystem::path& committed, const std::filesystem::path& replaced);

// `.NAME.rodfab-old-PID-N` beside `file`: the name under which process `pid` keeps the n-th file its
// commits replaced (and a job writer's recovery keeps a dead writer's, when NAME is taken).
std::filesystem::path previousVersionName(const std::filesystem::path& file, long pid, int n);

// Takes back an output committed through commitRegistered (a command whose later outputs failed: all
// or none): removed, and the file it replaced put back. Does nothing for a path not registered.
void withdrawCommitted(const std::filesystem::path& committed);

// Called by main with the owner it holds and the command's exit code: blocks further signals (they
// change nothing after this), then `outputs.finish(exitCode)`.
int finishCommand(CommandOutputs& outputs, int exitCode);

// For a command that cannot go on (std::terminate): blocks signals, removes every registered path
// and returns 128 + signal when one is pending, else `exitCode`.
int abandonCommand(int exitCode);

}  // namespace rodfab::common
