#include "slicer/profile_option.hpp"

#include "common/quoted_text.hpp"

#include <iostream>

namespace rodfab::cli {

void addProfileOptions(po::options_description& options) {
  options.add_options()
      ("profile", po::value<std::string>()->default_value(kDefaultProfileName)->value_name("NAME|FILE"),
       "printer profile: a bundled name (rodfab profiles lists them) or a profile file")
      ("print-mode", po::value<std::string>()->value_name("MODE"),
       "the printer's print mode, for profiles that have several (e.g. high-speed | high-mix); default: the profile's first");
}

std::optional<printer_profiles::Profile> profileFromOptions(const po::variables_map& vm, const std::string& command,
                                                            const std::string& consequence, int& exitCode) {
  printer_profiles::Profile profile;
  try {
    profile = printer_profiles::loadProfile(vm["profile"].as<std::string>());
  } catch (const printer_profiles::ProfileError& e) {
    std::cerr << e.what() << '\n' << consequence << '\n';
    exitCode = kFailed;
    return std::nullopt;
  }
  if (!vm.count("print-mode")) return profile;
  const std::string mode = vm["print-mode"].as<std::string>();
  std::string known;
  for (const printer_profiles::PrintMode& m : profile.printModes) {
    if (m.name == mode) return printer_profiles::withPrintMode(profile, mode);
    known += (known.empty() ? "" : ", ") + m.name;
  }
  exitCode = usageError(command, "--print-mode: expected " + (known.empty() ? "none (the " + profile.name + " profile has no print modes)"
                                                                             : "one of the " + profile.name + " profile's modes: " + known) +
                                     ", got " + common::quotedFromFile(mode));
  return std::nullopt;
}

}  // namespace rodfab::cli
