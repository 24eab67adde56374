// The private parts of reading printer profiles (profile_reader.cpp reads the document,
// profile_sections.cpp its sections): the JSON helpers, the Validator that collects every violation at
// its JSON path, and one reader per section of the format (profile.hpp says what each holds). Not
// thread-safe: one Validator per profile read.
#pragma once

#include "common/json_input.hpp"
#include "common/quoted_text.hpp"
#include "printer_profiles/profile.hpp"

#include <nlohmann/json.hpp>

#include <cctype>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace rodfab::printer_profiles::detail {

using nlohmann::json;

using common::describeJson;
using common::indexPath;
using common::memberPath;

inline std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

inline std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}


// Collects every violation; each accessor returns what it could read so later checks can go on.
class Validator {
public:
  std::vector<ProfileIssue> issues;

  void fail(const std::string& path, const std::string& message) { common::listIssue(issues, ProfileIssue{path, message}); }

  const json* object(const json& parent, const std::string& path, const std::string& key) {
    const json* j = require(parent, path, key, "an object");
    if (j && !j->is_object()) {
      fail(memberPath(path, key), "expected an object, got " + describeJson(*j));
      return nullptr;
    }
    return j;
  }

  const json* require(const json& parent, const std::string& path, const std::string& key, const std::string& what) {
    auto it = parent.find(key);
    if (it == parent.end()) {
      fail(memberPath(path, key), "missing; expected " + what);
      return nullptr;
    }
    return &*it;
  }

  std::optional<std::string> string(const json& parent, const std::string& path, const std::string& key,
                                    std::size_t maxLength = kMaxTextLength) {
    const json* j = require(parent, path, key, "a string");
    if (!j) return std::nullopt;
    // No control characters: a profile's strings reach messages, summaries and reports (a printer
    // named "\x1b[2J" cleared the terminal of `rodfab profiles`).
    if (!j->is_string() || j->get<std::string>().empty() || j->get<std::string>().size() > maxLength ||
        common::holdsControlCharacters(j->get<std::string>())) {
      fail(memberPath(path, key), "expected a non-empty string of at most " + std::to_string(maxLength) +
                                      " bytes without control characters, got " + describeJson(*j));
      return std::nullopt;
    }
    return j->get<std::string>();
  }

  // A finite number in (lo, hi] (or [lo, hi] when `closedBelow`).
  std::optional<double> real(const json& j, const std::string& path, const std::string& what, double lo, double hi,
                             bool closedBelow = false) {
    const bool ok = j.is_number() && std::isfinite(j.get<double>()) &&
                    (closedBelow ? j.get<double>() >= lo : j.get<double>() > lo) && j.get<double>() <= hi;
    if (!ok) {
      fail(path, "expected " + what + " (a number " + (closedBelow ? ">= " : "> ") + number(lo) + " and <= " + number(hi) +
                     "), got " + describeJson(j));
      return std::nullopt;
    }
    return j.get<double>();
  }

  std::optional<int> integer(const json& j, const std::string& path, const std::string& what, int lo, int hi) {
    const bool ok = (j.is_number_unsigned() && j.get<std::uint64_t>() <= static_cast<std::uint64_t>(hi) &&
                     static_cast<long long>(j.get<std::uint64_t>()) >= lo) ||
                    (j.is_number_integer() && !j.is_number_unsigned() && j.get<long long>() >= lo && j.get<long long>() <= hi);
    if (!ok) {
      fail(path, "expected " + what + " (an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + "), got " +
                     describeJson(j));
      return std::nullopt;
    }
    return static_cast<int>(j.get<long long>());
  }

  template <std::size_t N, typename Read>
  bool array(const json& parent, const std::string& path, const std::string& key, const std::string& what, Read read) {
    const json* j = require(parent, path, key, "an array of " + std::to_string(N) + " " + what);
    if (!j) return false;
    const std::string p = memberPath(path, key);
    if (!j->is_array() || j->size() != N) {
      fail(p, "expected an array of " + std::to_string(N) + " " + what + ", got " + describeJson(*j));
      return false;
    }
    bool ok = true;
    for (std::size_t i = 0; i < N; ++i) ok = read((*j)[i], indexPath(p, i), i) && ok;
    return ok;
  }

  // A file name inside the job: portable (see portableNameProblem).
  std::optional<std::string> fileName(const json& parent, const std::string& path, const std::string& key) {
    const std::optional<std::string> name = string(parent, path, key, kMaxFileNameLength);
    if (!name) return std::nullopt;
    if (const std::string problem = portableNameProblem(*name); !problem.empty()) {
      fail(memberPath(path, key), "\"" + *name + "\" is not a portable file name: " + problem);
      return std::nullopt;
    }
    return name;
  }
};

inline constexpr double kMinVoxelMm = 1e-4, kMaxVoxelMm = 100.0, kMaxTrayMm = 10000.0, kMaxDensity = 100.0;

// Each reads (or checks) one part of the profile into `p`, recording every violation in `v`; the
// checks across parts (the tray in voxels, unique file names, the .gcvf rules) come after them all.
void readResolution(Validator& v, const json& doc, Profile& p);
void readOutput(Validator& v, const json& doc, Profile& p);
void readPrintModes(Validator& v, const json& doc, Profile& p);
void checkGcvf(Validator& v, const Profile& p);
void readMaterials(Validator& v, const json& doc, Profile& p);
void readImage(Validator& v, const json& doc, Profile& p);
void readRest(Validator& v, const json& doc, Profile& p);
void checkTrayVoxels(Validator& v, const Profile& p);
void checkNamesUnique(Validator& v, const Profile& p);

}  // namespace rodfab::printer_profiles::detail
