// Fuzzes every command's command line: option syntax, value parsers and range checks, up to the
// point where the command would read its inputs (cli::commandLineAccepted). The input is the
// argument list, one argument per line; the first line names the command. Properties checked: no
// crash, no sanitizer report, and the exit code is 0 (help) or 2 (a usage error) when the command
// stops before its work, 1 only for input errors found while checking (e.g. an unknown profile).
#include "slicer/command.hpp"
#include "slicer/options.hpp"

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace {

struct StopBeforeWork {};

[[noreturn]] void stopBeforeWork() { throw StopBeforeWork{}; }

std::vector<std::string> splitLines(const std::uint8_t* data, std::size_t size) {
  std::vector<std::string> out(1);
  for (std::size_t i = 0; i < size; ++i) {
    if (data[i] == '\n') out.emplace_back();
    else out.back() += static_cast<char>(data[i]);
  }
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace rodfab::cli;
  static const bool quiet = [] {
    setCommandLineAcceptedHook(stopBeforeWork);
    std::cout.setstate(std::ios::failbit);  // help texts and summaries are not under test
    std::cerr.setstate(std::ios::failbit);
    return true;
  }();
  (void)quiet;
  if (size > 4096) return 0;
  std::vector<std::string> args = splitLines(data, size);
  for (const std::string& a : args)
    if (a.find('\0') != std::string::npos) return 0;  // not representable in argv
  const Command* command = findCommand(args.front());
  if (!command) return 0;
  args.erase(args.begin());
  try {
    const int code = runCommand(*command, args);
    if (code != kOk && code != kUsage && code != kFailed) std::abort();
  } catch (const StopBeforeWork&) {
  }
  return 0;
}
