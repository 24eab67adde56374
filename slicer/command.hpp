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

struct Command {
  const char* name;
  const char* summary;
  // `args` excludes the program and subcommand names.
  int (*run)(const std::vector<std::string>& args);
};

// Every command, in the order `rodfab` lists them; nullptr for an unknown name.
std::span<const Command> commands();
const Command* findCommand(const std::string& name);
void printUsage(std::ostream& out);

// Runs `command`; every failure becomes an exit code and one message on stderr (Interrupted:
// 128 + signal; out of memory and other errors: kFailed). Does not install handlers or a budget.
int runCommand(const Command& command, const std::vector<std::string>& args);

int runValidate(const std::vector<std::string>& args);
int runVoxelize(const std::vector<std::string>& args);
int runSlice(const std::vector<std::string>& args);
int runCoupons(const std::vector<std::string>& args);
int runCalibrate(const std::vector<std::string>& args);
int runProfiles(const std::vector<std::string>& args);
int runInspect(const std::vector<std::string>& args);
int runDitherReport(const std::vector<std::string>& args);
int runSimulate(const std::vector<std::string>& args);
int runOptimize(const std::vector<std::string>& args);
int runRodsFromMesh(const std::vector<std::string>& args);
int runRodsFromCad(const std::vector<std::string>& args);

}  // namespace rodfab::cli
