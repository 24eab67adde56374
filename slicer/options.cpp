#include "slicer/options.hpp"

#include "slicer/command.hpp"

#include "geometry/design_file.hpp"

#include <iostream>

namespace rodfab::cli {

std::optional<int> parseOptions(const std::string& command, const std::string& synopsis,
                                po::options_description& options, const po::positional_options_description& positional,
                                const std::vector<std::string>& args, po::variables_map& vm) {
  options.add_options()("help,h", "show this help");
  try {
    po::store(po::command_line_parser(args).options(options).positional(positional).run(), vm);
    if (vm.count("help")) {
      std::cout << "usage: rodfab " << command << ' ' << synopsis << "\n\n" << options << '\n';
      return kOk;
    }
    po::notify(vm);
  } catch (const po::error& e) {
    std::cerr << "rodfab " << command << ": " << e.what() << "\nusage: rodfab " << command << ' ' << synopsis
              << "\n(rodfab " << command << " --help lists the options)\n";
    return kUsage;
  }
  return std::nullopt;
}

int usageError(const std::string& command, const std::string& message) {
  std::cerr << "rodfab " << command << ": " << message << "\n(rodfab " << command << " --help lists the options)\n";
  return kUsage;
}

std::optional<geometry::RodStructure> readDesignOrReport(const std::string& file, const std::string& consequence) {
  try {
    return geometry::readDesign(file);
  } catch (const geometry::DesignError& e) {
    std::cerr << e.what() << '\n' << file << ": the design is not valid; " << consequence << '\n';
    return std::nullopt;
  }
}

std::optional<int> threadCount(const std::string& command, const po::variables_map& vm) {
  const int threads = vm["threads"].as<int>();
  if (threads >= 0) return threads;
  usageError(command, "--threads: expected 0 (all cores) or a positive count, got " + std::to_string(threads));
  return std::nullopt;
}

}  // namespace rodfab::cli
