// Reading printer profiles: strict JSON (no key twice, bounded nesting), then every check of the
// format, each violation recorded at its JSON path (profile.hpp).
#include "printer_profiles/profile.hpp"
#include "printer_profiles/profile_validator.hpp"

#include "common/located_issues.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <sstream>

namespace rodfab::printer_profiles {

using nlohmann::json;
using namespace detail;

namespace {

// A refusal raised while nlohmann builds the document (too deep, a key twice).
struct StructureIssue {
  ProfileIssue issue;
};

// nlohmann keeps the last of two equal keys without a word and nests as deep as the input goes: this
// callback sees every parse event, tracks the JSON path, and stops both while the document is built.
class StructureCheck {
public:
  bool operator()(int, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start:
        if (stack_.size() >= static_cast<std::size_t>(kMaxProfileDepth))
          throw StructureIssue{{path(), "nested deeper than " + std::to_string(kMaxProfileDepth) +
                                            " levels of objects and arrays; a printer profile needs a few"}};
        stack_.push_back({event == json::parse_event_t::array_start, 0, {}, {}});
        break;
      case json::parse_event_t::key: {
        Frame& frame = stack_.back();
        frame.key = parsed.get<std::string>();
        if (!frame.keys.insert(frame.key).second)
          throw StructureIssue{{path(), "this key appears twice in its object; expected each key once"}};
        break;
      }
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        stack_.pop_back();
        elementDone();
        break;
      case json::parse_event_t::value:
        elementDone();
        break;
    }
    return true;
  }

private:
  struct Frame {
    bool array = false;
    std::size_t next = 0;  // arrays: index of the element being read
    std::string key;       // objects: key of the member being read
    std::set<std::string> keys;
  };

  void elementDone() {
    if (!stack_.empty() && stack_.back().array) ++stack_.back().next;
  }
  // Path of the element being read, e.g. `materials[1].name`.
  std::string path() const {
    std::string p;
    for (const Frame& f : stack_) {
      if (f.array) p = indexPath(p, f.next);
      else if (!f.key.empty()) p = memberPath(p, f.key);
      else break;  // an object before its first key
    }
    return p;
  }

  std::vector<Frame> stack_;
};

json parseStrictly(const std::string& text, const std::string& sourceName) {
  try {
    return json::parse(text, StructureCheck());
  } catch (const StructureIssue& e) {
    throw ProfileError(sourceName, {e.issue});
  } catch (const json::exception& e) {  // parse_error, or out_of_range for a number too large (1e400)
    throw ProfileError(sourceName, {{"", "not valid JSON: " + common::printableJsonError(e.what())}});
  }
}

}  // namespace


std::string portableNameProblem(const std::string& name) {
  if (name.empty()) return "it is empty";
  if (name.size() > kMaxFileNameLength) return "longer than " + std::to_string(kMaxFileNameLength) + " characters";
  for (const char c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-')
      return std::string("it holds ") +
             (c == '/' || c == '\\' ? "a path separator" : c == ':' ? "':' (a drive letter or stream on Windows)" : "a character") +
             " outside letters, digits, '.', '_' and '-'";
  if (name.front() == '.' || name.front() == '-') return "it starts with '" + std::string(1, name.front()) + "'";
  if (name.back() == '.') return "it ends with '.' (Windows drops it)";
  const std::string device = lower(name.substr(0, name.find('.')));
  static const std::set<std::string> kDevices = {"con", "prn", "aux", "nul"};
  if (kDevices.contains(device) ||
      (device.size() == 4 && (device.starts_with("com") || device.starts_with("lpt")) && device[3] >= '1' && device[3] <= '9'))
    return "\"" + name.substr(0, name.find('.')) + "\" is a device name on Windows";
  return "";
}

ProfileError::ProfileError(std::string file, std::vector<ProfileIssue> issues)
    : IssueListError(common::formatLocatedIssues(file, issues), file, issues) {}

Profile parseProfile(const std::string& text, const std::string& sourceName) {
  if (text.size() > kMaxProfileBytes)
    throw ProfileError(sourceName, {{"", "is " + std::to_string(text.size()) + " bytes; a printer profile is at most " +
                                             std::to_string(kMaxProfileBytes)}});
  const json doc = parseStrictly(text, sourceName);
  if (!doc.is_object()) throw ProfileError(sourceName, {{"", "expected a JSON object at the top level"}});
  Validator v;
  Profile p;
  p.source = sourceName;
  if (auto format = v.string(doc, "", "format"); format && *format != kProfileFormat)
    v.fail("format", "expected \"" + std::string(kProfileFormat) + "\", got \"" + *format + "\"");
  p.name = v.string(doc, "", "name").value_or("");
  // Jobs name their profile and inspect looks it up by that name: it must be a plain, portable name.
  if (const std::string problem = portableNameProblem(p.name); !p.name.empty() && !problem.empty())
    v.fail("name", "\"" + p.name + "\" is not a portable profile name: " + problem);
  p.printer = v.string(doc, "", "printer").value_or("");
  if (auto it = doc.find("description"); it != doc.end()) p.description = v.string(doc, "", "description").value_or("");
  readOutput(v, doc, p);
  readResolution(v, doc, p);
  readPrintModes(v, doc, p);
  readRest(v, doc, p);
  readMaterials(v, doc, p);
  readImage(v, doc, p);
  checkTrayVoxels(v, p);
  checkNamesUnique(v, p);
  if (p.jobFormat == JobFormat::Gcvf) checkGcvf(v, p);
  if (!v.issues.empty()) throw ProfileError(sourceName, v.issues);
  return p;
}

}  // namespace rodfab::printer_profiles
