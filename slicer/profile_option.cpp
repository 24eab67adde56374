#include "slicer/profile_option.hpp"

#include <iostream>

namespace rodfab::cli {

void addProfileOptions(po::options_description& options) {
  options.add_options()
      ("profile", po::value<std::string>()->default_value(kDefaultProfileName)->value_name("NAME|FILE"),
       "printer profile: a bundled name (rodfab profiles lists them) or a profile file")
      ("print-mode", po::value<std::string>()->value_name("MODE"),
       "the printer's print mode, for profiles that have several (e.g. high-speed | high-mix); default: the profile's first");
}

std::optional<printer_profiles::Profile> profileFromOptions(const po::variables_map& vm, const std::string& consequence) {
  try {
    printer_profiles::Profile profile = printer_profiles::loadProfile(vm["profile"].as<std::string>());
    if (vm.count("print-mode")) profile = printer_profiles::withPrintMode(profile, vm["print-mode"].as<std::string>());
    return profile;
  } catch (const printer_profiles::ProfileError& e) {
    std::cerr << e.what() << '\n' << consequence << '\n';
    return std::nullopt;
  }
}

}  // namespace rodfab::cli
