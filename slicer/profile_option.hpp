// --profile and --print-mode, for every command that needs the printer's voxel (the profile is the only
// source of the voxel size: nothing in rodfab assumes one printer).
#pragma once

#include "printer_profiles/profile.hpp"
#include "slicer/options.hpp"

#include <optional>
#include <string>

namespace rodfab::cli {

// The profile a command uses when --profile is not given.
inline constexpr const char* kDefaultProfileName = printer_profiles::kDefaultProfileName;

// Declares --profile NAME|FILE (default kDefaultProfileName) and --print-mode MODE.
void addProfileOptions(po::options_description& options);

// The profile --profile names, in the --print-mode given (default: the profile's first mode). When it
// cannot be used, prints why on stderr and returns nullopt with `exitCode` set: kFailed for a profile
// file's errors (then "CONSEQUENCE"), kUsage for a --print-mode the profile does not have (a usage
// error of `command`, naming the modes it has).
std::optional<printer_profiles::Profile> profileFromOptions(const po::variables_map& vm, const std::string& command,
                                                            const std::string& consequence, int& exitCode);

}  // namespace rodfab::cli
