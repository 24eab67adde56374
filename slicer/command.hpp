// The rodfab subcommands: each lives in its own cmd_*.cpp and is listed in main.cpp.
#pragma once

#include <ostream>
#include <span>
#include <string>
#include <vector>

namespace rodfab::cli {

// Exit codes shared by every subcommand.
enum ExitCode : int {
  kOk = 0,
  kFailed = 1,  // bad input file, failed check, I/O error
  kUsage = 2,   // bad command line
};

// A command's run: `args` excludes the program and subcommand names; returns the exit code.
using RunCommand = int(const std::vector<std::string>& args);

struct Command {
  const char* name;
  const char* summary;
  RunCommand* run;
};

// Every command, in the order `rodfab` lists them; nullptr for an unknown name.
std::span<const Command> commands();
const Command* findCommand(const std::string& name);
void printUsage(std::ostream& out);

// Runs `command`; every failure becomes an exit code and one message on stderr (Interrupted:
// 128 + signal; out of memory and other errors: kFailed). Does not install handlers or a budget.
int runCommand(const Command& command, const std::vector<std::string>& args);

// The commands' runs, one per cmd_*.cpp.
RunCommand runValidate, runVoxelize, runSlice, runCoupons, runCalibrate, runProfiles, runInspect, runDitherReport,
    runSimulate, runOptimize, runRodsFromMesh, runRodsFromCad;

}  // namespace rodfab::cli
