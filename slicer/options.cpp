#include "slicer/options.hpp"

#include "slicer/command.hpp"

#include "common/memory_budget.hpp"
#include "mechanics/mechanics_file.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <thread>

namespace rodfab::cli {

namespace {

// Parses `args` against `options` (and the undocumented `hidden` ones) into `vm`; throws po::error.
void storeArguments(const std::vector<std::string>& args, const po::options_description& options,
                    const po::positional_options_description& positional, const po::options_description* hidden,
                    po::variables_map& vm) {
  po::options_description all;
  all.add(options);
  if (hidden) all.add(*hidden);
  po::store(po::command_line_parser(args).options(all).positional(positional).run(), vm);
}

// Boost's error text substitutes placeholders such as %canonical_option% with the user's tokens in a loop
// that never ends when a token itself contains the placeholder (`-%canonical_option%o` hangs what()).
// The message is therefore taken from a second parse of the same arguments with every '%' shown as
// U+FF05 (fullwidth percent), which fails the same way and whose tokens cannot contain a placeholder.
std::string parseErrorMessage(const po::error& error, const std::vector<std::string>& args,
                              const po::options_description& options, const po::positional_options_description& positional,
                              const po::options_description* hidden) {
  const bool hasPercent = std::any_of(args.begin(), args.end(), [](const std::string& a) { return a.find('%') != std::string::npos; });
  if (!hasPercent) return error.what();
  std::vector<std::string> shown = args;
  for (std::string& a : shown)
    for (std::size_t at = a.find('%'); at != std::string::npos; at = a.find('%', at + 3)) a.replace(at, 1, "\xEF\xBC\x85");
  try {
    po::variables_map unused;
    storeArguments(shown, options, positional, hidden, unused);
    po::notify(unused);
  } catch (const po::error& e) {
    return e.what();
  }
  return "the command line could not be read (an argument contains '%')";
}

// An option's value name as --help shows it, without the " (=default)" Boost appends.
std::string valueName(const po::option_description& option) {
  const std::string name = option.semantic()->name();
  return name.substr(0, name.find(" (="));
}

// "[word]": an optional part of a synopsis. (Built by appending: GCC 12 warns falsely, -Wrestrict,
// on "[" + std::string&&.)
std::string bracketed(const std::string& word) {
  std::string out = "[";
  out += word;
  out += ']';
  return out;
}

// The first option (or positional argument) given as an empty string, "" when none: every text
// option names a file, a profile, a method or a quantity, so an empty one is a slip of the shell
// (-o "$UNSET"), refused as a usage error before anything is read or written.
// Switches (--quiet) hold an empty string too, so only options that take a value count.
std::string firstEmptyValue(const po::variables_map& vm, const po::options_description& options,
                            const po::options_description* hidden) {
  const auto takesValue = [&](const std::string& name) {
    const po::option_description* o = options.find_nothrow(name, false);
    if (!o && hidden) o = hidden->find_nothrow(name, false);
    return o && o->semantic()->max_tokens() > 0;
  };
  for (const auto& [name, value] : vm) {
    const auto* text = boost::any_cast<std::string>(&value.value());
    if (text && text->empty() && !value.defaulted() && takesValue(name)) return name;
  }
  return "";
}

// The options that name a file the command writes.
constexpr const char* kOutputOptions[] = {"output", "plot", "render"};

// The first output option given as "-", "" when none. By custom "-" means standard output, which no
// command writes to: every output goes to a temporary name, is checked, then renamed into place (a
// job may be a folder), and replaces only a file rodfab wrote. Without this check "-o -" wrote a file
// named "-".
std::string firstStandardOutput(const po::variables_map& vm) {
  for (const char* name : kOutputOptions)
    if (vm.count(name) && vm[name].as<std::string>() == "-") return name;
  return "";
}

}  // namespace

std::string synopsisOf(const po::options_description& options, const po::positional_options_description& positional) {
  std::string out;
  const auto append = [&](const std::string& word) { out += (out.empty() ? "" : " ") + word; };
  std::vector<std::string> positionalNames;
  for (unsigned i = 0; i < positional.max_total_count(); ++i) {
    const std::string& name = positional.name_for_position(i);
    const po::option_description& option = options.find(name, false);
    positionalNames.push_back(name);
    const std::string value = valueName(option);
    append(option.semantic()->is_required() ? value : bracketed(value));
  }
  for (const auto& option : options.options()) {
    if (std::ranges::find(positionalNames, option->long_name()) != positionalNames.end()) continue;
    std::string word = "--" + option->long_name();
    if (option->semantic()->max_tokens() > 0) word += ' ' + valueName(*option);
    append(option->semantic()->is_required() ? word : bracketed(word));
  }
  return out;
}

std::optional<int> parseOptions(const std::string& command, po::options_description& options,
                                const po::positional_options_description& positional,
                                const std::vector<std::string>& args, po::variables_map& vm,
                                const po::options_description* hidden) {
  const std::string synopsis = synopsisOf(options, positional);
  options.add_options()("help,h", "show this help")
      ("max-memory", po::value<std::string>()->value_name("SIZE"),
       "memory budget, e.g. 8G or 512M (default: 80 % of this machine's memory); work beyond it is refused");
  try {
    storeArguments(args, options, positional, hidden, vm);
    if (vm.count("help")) {
      std::cout << "usage: rodfab " << command << ' ' << synopsis << "\n\n" << options << '\n';
      return kOk;
    }
    po::notify(vm);
    if (const std::string empty = firstEmptyValue(vm, options, hidden); !empty.empty())
      return usageError(command, "--" + empty + ": expected a value, got an empty string");
    if (const std::string dash = firstStandardOutput(vm); !dash.empty())
      return usageError(command, "--" + dash + ": '-' (standard output) is not supported: rodfab writes its outputs to files only; "
                                 "name a file (./- for a file named '-')");
    if (vm.count("max-memory")) {
      const std::string text = vm["max-memory"].as<std::string>();
      const std::optional<std::uint64_t> bytes = common::parseByteSize(text);
      if (!bytes) return usageError(command, "--max-memory: expected a size such as 8G or 512M, got '" + text + "'");
      try {
        common::setMemoryBudget(*bytes);
      } catch (const std::invalid_argument& e) {
        return usageError(command, std::string("--max-memory: ") + e.what());
      }
    }
  } catch (const po::error& e) {
    std::cerr << "rodfab " << command << ": " << parseErrorMessage(e, args, options, positional, hidden)
              << "\nusage: rodfab " << command << ' ' << synopsis
              << "\n(rodfab " << command << " --help lists the options)\n";
    return kUsage;
  }
  return std::nullopt;
}

std::optional<int> parseOptionsWithInput(const std::string& command, po::options_description& options,
                                         const std::string& positional, const std::vector<std::string>& args,
                                         po::variables_map& vm) {
  po::positional_options_description one;
  one.add(positional.c_str(), 1);
  return parseOptions(command, options, one, args, vm);
}

std::optional<int> parseOptionsWithInput(const std::string& command, void (*declare)(po::options_description&),
                                         const std::string& positional, const std::vector<std::string>& args,
                                         po::variables_map& vm) {
  po::options_description options("options");
  declare(options);
  return parseOptionsWithInput(command, options, positional, args, vm);
}

int usageError(const std::string& command, const std::string& message) {
  std::cerr << "rodfab " << command << ": " << message << "\n(rodfab " << command << " --help lists the options)\n";
  return kUsage;
}

std::optional<mechanics::Design> readDesignOrReport(const std::string& file, const std::string& consequence) {
  try {
    return mechanics::readDesign(file);
  } catch (const geometry::DesignError& e) {
    std::cerr << e.what() << '\n' << file << ": the design is not valid; " << consequence << '\n';
    return std::nullopt;
  }
}

std::optional<int> threadCount(const std::string& command, const po::variables_map& vm) {
  const int threads = vm["threads"].as<int>();
  if (threads >= 0 && threads <= kMaxThreads) return threads;
  usageError(command, "--threads: expected 0 (all cores) or a count from 1 to " + std::to_string(kMaxThreads) + ", got " +
                          std::to_string(threads));
  return std::nullopt;
}

void addThreadsOption(po::options_description& options, const std::string& what) {
  options.add_options()("threads", po::value<int>()->default_value(0)->value_name("N"),
                        ("worker threads, 0 = all cores, at most " + std::to_string(kMaxThreads) + "; " + what).c_str());
}

ThreadLimit::ThreadLimit(int threads)
    : workers_(threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()))) {
  if (threads > 0)
    control_ = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
}

ThreadLimit::~ThreadLimit() = default;

void validate(boost::any& out, const std::vector<std::string>& values, Seed*, int) {
  po::validators::check_first_occurrence(out);
  const std::string& text = po::validators::get_single_string(values);
  const bool digits = !text.empty() && text.size() <= 20 &&
                      std::all_of(text.begin(), text.end(), [](unsigned char c) { return c >= '0' && c <= '9'; });
  errno = 0;
  const unsigned long long v = digits ? std::strtoull(text.c_str(), nullptr, 10) : 0;
  if (!digits || errno == ERANGE)
    throw po::error("--seed: expected a whole number from 0 to 18446744073709551615, got '" + text + "'");
  out = Seed{v};
}

std::ostream& operator<<(std::ostream& out, const Seed& seed) { return out << seed.value; }

std::optional<int> intOption(const std::string& command, const po::variables_map& vm, const std::string& name, int lo,
                             int hi) {
  const int v = vm[name].as<int>();
  if (v >= lo && v <= hi) return v;
  usageError(command, "--" + name + ": expected a whole number from " + std::to_string(lo) + " to " + std::to_string(hi) +
                          ", got " + std::to_string(v));
  return std::nullopt;
}

std::optional<double> realOption(const std::string& command, const po::variables_map& vm, const std::string& name,
                                 double lo, double hi, const std::string& unit) {
  const double v = vm[name].as<double>();
  if (std::isfinite(v) && v >= lo && v <= hi) return v;
  std::ostringstream message;
  message << "--" << name << ": expected " << unit << " from " << lo << " to " << hi << ", got " << v;
  usageError(command, message.str());
  return std::nullopt;
}

namespace {
void (*acceptedHook)() = nullptr;
}

void commandLineAccepted() {
  if (acceptedHook) acceptedHook();
}

void setCommandLineAcceptedHook(void (*hook)()) { acceptedHook = hook; }

void warnLeftoverPreviousVersions(const std::filesystem::path& output) {
  for (const std::filesystem::path& copy : common::leftoverPreviousVersions(output))
    std::cerr << "warning: " << copy.string() << " is what " << output.string()
              << " held before a rodfab run that was killed (it never finished) replaced it: rename it back to restore it, "
                 "or delete it\n";
}

bool outputAllowed(const std::string& output, const std::vector<std::filesystem::path>& inputs,
                   const common::OutputPolicy& policy) {
  try {
    warnLeftoverPreviousVersions(output);  // first: removing a stale second link changes the output's link count
    common::checkOutputPath(output, inputs, policy);
    return true;
  } catch (const std::runtime_error& e) {
    std::cerr << e.what() << "\nnothing was written\n";
    return false;
  }
}

}  // namespace rodfab::cli
