#include "slicer/profile_option.hpp"

#include "common/json_input.hpp"
#include "common/quoted_text.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <iostream>

namespace rodfab::cli {

void addProfileOptions(po::options_description& options) {
  options.add_options()
      ("profile", po::value<std::string>()->default_value(kDefaultProfileName)->value_name("NAME|FILE"),
       "printer profile: a bundled name (rodfab profiles lists them) or a profile file")
      ("print-mode", po::value<std::string>()->value_name("MODE"),
       "the printer's print mode, for profiles that have several (e.g. high-speed | high-mix); default: the profile's first");
}

namespace {

// A profile file may take a bundled profile's name only as a copy of it: a job records its profile by
// name, and `inspect` checks it against the bundled profile of that name (a file with another tray made
// jobs that passed their own check and failed inspect's). Compared as JSON values, not bytes.
void refuseTakenName(const printer_profiles::Profile& profile) {
  namespace pp = printer_profiles;
  const std::vector<std::string> bundled = pp::bundledProfileNames();
  if (std::find(bundled.begin(), bundled.end(), profile.name) == bundled.end()) return;
  const std::filesystem::path own = pp::bundledProfileDir() / (profile.name + ".json");
  std::error_code ec;
  if (std::filesystem::equivalent(profile.source, own, ec)) return;
  const auto json = [](const std::filesystem::path& file) {
    try {
      return nlohmann::json::parse(common::readBoundedFile(file.string(), pp::kMaxProfileBytes));
    } catch (const std::exception&) {
      return nlohmann::json();  // unreadable now: differs from anything read before
    }
  };
  const nlohmann::json mine = json(profile.source);
  if (!mine.is_null() && mine == json(own)) return;
  throw pp::ProfileError(profile.source.string(),
                         {{"name", "\"" + profile.name + "\" is a bundled profile's name, and this file is not that profile: give it a name of "
                                   "its own (jobs record their profile by name, and inspect checks a job against the bundled profile of "
                                   "its name)"}});
}

}  // namespace

std::optional<printer_profiles::Profile> profileFromOptions(const po::variables_map& vm, const std::string& command,
                                                            const std::string& consequence, int& exitCode) {
  printer_profiles::Profile profile;
  try {
    profile = printer_profiles::loadProfile(vm["profile"].as<std::string>());
    refuseTakenName(profile);
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
