// Shared Boost.Program_options plumbing for the subcommands: --help and consistent usage errors.
#pragma once

#include "common/output_file.hpp"
#include "slicer/command.hpp"
#include "geometry/rod.hpp"
#include "mechanics/mechanics_spec.hpp"

#include <boost/program_options.hpp>
#include <tbb/global_control.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace rodfab::cli {

namespace po = boost::program_options;

// A command's synopsis, built from its options so that the two cannot drift: the positional arguments
// first, as their value names ("DESIGN.json"; "[PROFILE]" when optional), then every option in the order
// declared: "--name VALUE" when required, "[--name VALUE]" otherwise, "[--name]" for a flag. VALUE is
// the option's value_name(), which every option that takes a value sets (Boost's "arg" otherwise).
std::string synopsisOf(const po::options_description& options, const po::positional_options_description& positional);

// Parses `args` against `options` (+ positionals), which gain --help and --max-memory (applied here:
// common::setMemoryBudget; neither is in the synopsis). Prints "usage: rodfab COMMAND SYNOPSIS" (synopsisOf)
// and the options and returns kOk for --help, prints a usage error with the synopsis and returns kUsage
// for bad options; returns nullopt when the command should go on.
// `hidden` (optional) holds options accepted but not listed by --help nor the synopsis (old spellings).
std::optional<int> parseOptions(const std::string& command, po::options_description& options,
                                const po::positional_options_description& positional,
                                const std::vector<std::string>& args, po::variables_map& vm,
                                const po::options_description* hidden = nullptr);
// parseOptions for a command whose one positional argument is the value of the option named `positional`
// (its input file: "design", "mesh", ...).
std::optional<int> parseOptionsWithInput(const std::string& command, po::options_description& options,
                                         const std::string& positional, const std::vector<std::string>& args,
                                         po::variables_map& vm);
// The same for a command whose options `declare` adds to an options_description("options").
std::optional<int> parseOptionsWithInput(const std::string& command, void (*declare)(po::options_description&),
                                         const std::string& positional, const std::vector<std::string>& args,
                                         po::variables_map& vm);

// Prints "rodfab COMMAND: MESSAGE" and where the options are listed; returns kUsage.
int usageError(const std::string& command, const std::string& message);

// Each command calls this once its command line is checked, before it reads or writes any file or
// starts work. It does nothing unless a hook is set: the command-line fuzz target's hook stops there
// (by throwing), so fuzzing covers every option parser without running the work.
void commandLineAccepted();
void setCommandLineAcceptedHook(void (*hook)());

// Reads a design for a command that writes something. On an invalid design prints its errors and
// "FILE: the design is not valid; CONSEQUENCE" and returns nullopt (the command exits kFailed). The
// mechanics and optimize blocks are read and checked too (mechanics::readDesign).
std::optional<mechanics::Design> readDesignOrReport(const std::string& file, const std::string& consequence);

// A dithering seed: 0 .. 2^64 - 1, written in decimal digits only (so "-1" is refused, not wrapped).
struct Seed {
  std::uint64_t value = 0;
};
// Boost.Program_options' hook for parsing a Seed.
void validate(boost::any& out, const std::vector<std::string>& values, Seed*, int);
std::ostream& operator<<(std::ostream& out, const Seed& seed);  // for default values in --help

// The value of an integer option `name` in [lo, hi], or nullopt after a usage error naming the option.
std::optional<int> intOption(const std::string& command, const po::variables_map& vm, const std::string& name, int lo,
                             int hi);
// The value of a real option `name`, finite and in [lo, hi] (`unit` for the message), or nullopt.
std::optional<double> realOption(const std::string& command, const po::variables_map& vm, const std::string& name,
                                 double lo, double hi, const std::string& unit);

// Layers per streamed band: more than this only costs memory (a band beyond the part is the part).
inline constexpr int kMaxBandLayers = 4096;

// More threads than this only add overhead on any machine rodfab runs on (and TBB fails far beyond).
inline constexpr int kMaxThreads = 256;

// Declares --threads N (default 0: all cores); `what` says what the workers do and whether the
// result depends on their number ("the job is the same for any count").
void addThreadsOption(po::options_description& options, const std::string& what);

// The --threads value: 0 (all cores) or 1..kMaxThreads; nullopt (after a usage error) otherwise.
std::optional<int> threadCount(const std::string& command, const po::variables_map& vm);

// Every command's thread limit, for as long as it lives: `threads` > 0 caps TBB (every stage's
// parallel loops, the job writer's encoders) at that many workers; 0 leaves TBB's default (all
// cores). One per command, made after the command line is checked, on the command's thread.
class ThreadLimit {
public:
  explicit ThreadLimit(int threads);
  ~ThreadLimit();
  ThreadLimit(const ThreadLimit&) = delete;
  ThreadLimit& operator=(const ThreadLimit&) = delete;
  // The workers a command that splits its own work should plan for: `threads`, or this machine's
  // hardware threads (at least 1) for 0.
  int workers() const { return workers_; }

private:
  int workers_;
  std::unique_ptr<tbb::global_control> control_;
};

// A parsed command line: the command's settings, or the exit code to return at once (kOk after
// --help, kUsage after a usage error).
template <class Settings>
using Parsed = std::variant<Settings, int>;

// The exit code `parsed` holds, or `work(settings)`: a command's run is its parser and its work.
template <class Settings, class Work>
int runParsed(const Parsed<Settings>& parsed, Work&& work) {
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  return std::forward<Work>(work)(std::get<Settings>(parsed));
}

// runParsed for settings with a thread count (`threads`, checked): `work(settings)` runs once the command
// line is accepted (commandLineAccepted) and under that ThreadLimit.
template <class Settings, class Work>
int runAccepted(const Parsed<Settings>& parsed, Work&& work) {
  return runParsed(parsed, [&](const Settings& settings) {
    commandLineAccepted();
    const ThreadLimit limit(settings.threads);
    return work(settings);
  });
}

// runAccepted for settings that also name a design file (`design`): `work(settings, design)` with the
// design read (mechanics::readDesign), or kFailed after readDesignOrReport printed why it could not be.
template <class Settings, class Work>
int runOnDesign(const Parsed<Settings>& parsed, Work&& work) {
  return runAccepted(parsed, [&](const Settings& settings) {
    const std::optional<mechanics::Design> design = readDesignOrReport(settings.design, "nothing was written");
    return design ? work(settings, *design) : static_cast<int>(kFailed);
  });
}

// Checks that `output` may be written under `policy` (common::checkOutputPath); prints the reason and
// "nothing was written" and returns false otherwise (the command exits kFailed). First warns of earlier
// versions a killed run left beside it (warnLeftoverPreviousVersions).
// Warns on stderr, one line each, of the copies of `output` a killed rodfab run kept and never settled
// (common::leftoverPreviousVersions): where they are and that they are the user's to restore or delete.
void warnLeftoverPreviousVersions(const std::filesystem::path& output);

bool outputAllowed(const std::string& output, const std::vector<std::filesystem::path>& inputs,
                   const common::OutputPolicy& policy);

}  // namespace rodfab::cli
