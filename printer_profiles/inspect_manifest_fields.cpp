// Reading the untrusted manifest: parsed with limits (parseUntrustedJson), its values described for
// messages without serializing them, and typed access to its fields (Fields), each failure a finding.
#include "printer_profiles/inspect_manifest_fields.hpp"

#include "printer_profiles/job_archive.hpp"
#include "printer_profiles/job_reader.hpp"

#include "common/json_input.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace rodfab::printer_profiles {

using nlohmann::json;

namespace {

// A message parseJsonStrict made printable (it escapes what it quotes: controls, bytes that are not
// UTF-8, the backslash) in inspect's form, plain ASCII: the UTF-8 characters it kept as \xNN too.
// Not printableName, which would escape those escapes' backslashes a second time.
std::string asciiOnly(const std::string& printable) {
  std::string out;
  for (const char ch : printable) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c < 0x7f) {
      out += ch;
      continue;
    }
    char buf[8];
    std::snprintf(buf, sizeof buf, "\\x%02x", c);
    out += buf;
  }
  return out;
}

}  // namespace

json parseUntrustedJson(std::span<const std::uint8_t> text, std::size_t maxValues) {
  try {
    return common::parseJsonStrict(std::string(text.begin(), text.end()), common::kMaxJsonDepth, maxValues);
  } catch (const common::JsonInputError& e) {
    // The message first: a path 64 levels deep would hide it.
    std::size_t cut = 57;  // not inside a UTF-8 character
    while (e.path.size() > 60 && cut > 0 && (static_cast<unsigned char>(e.path[cut]) & 0xc0) == 0x80) --cut;
    const std::string where = e.path.size() > 60 ? e.path.substr(0, cut) + "..." : e.path;
    const std::string message = asciiOnly(e.message + (where.empty() ? "" : " (at " + where + ")"));
    if (dynamic_cast<const common::JsonTooManyValues*>(&e)) throw UntrustedJsonTooLarge(message);
    throw std::runtime_error(message);
  } catch (const json::exception& e) {  // a number beyond a double
    throw std::runtime_error("not JSON (" + asciiOnly(common::printableJsonError(e.what())) + ")");
  }
}

namespace manifest_input {

using common::memberPath;

// A short description of an untrusted value, for messages: never serializes containers.
std::string describe(const json& j) {
  if (j.is_string()) {
    const std::string& s = j.get_ref<const std::string&>();
    std::string quoted = "\"";  // built with += : GCC 12 warns falsely (-Wrestrict) of "\"" + std::string
    quoted += printableName(s.size() > 60 ? s.substr(0, 57) + "..." : s);
    quoted += '"';
    return quoted;
  }
  if (j.is_number_integer() || j.is_number_unsigned() || j.is_boolean()) return j.dump();  // scalars only
  if (j.is_number_float()) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.9g", j.get<double>());
    return buf;
  }
  return std::string("a") + (j.is_object() || j.is_array() ? "n " : " ") + j.type_name();
}

bool nearlyEqual(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max({1.0, std::abs(a), std::abs(b)}); }

void Fields::fail(const std::string& path, const std::string& message) { findings_.at(kManifestName, path + ": " + message); }

const json* Fields::get(const json& parent, const std::string& path, const std::string& key, const char* what) {
  const auto it = parent.is_object() ? parent.find(key) : parent.end();
  if (it == parent.end()) {
    fail(memberPath(path, key), std::string("missing; expected ") + what);
    return nullptr;
  }
  return &*it;
}

// parent[key] when `isKind` holds for it (`what`: "an object", ...); nullptr after an issue.
const json* Fields::ofKind(const json& parent, const std::string& path, const std::string& key, const char* what,
                           bool (json::*isKind)() const noexcept) {
  const json* j = get(parent, path, key, what);
  if (j && !(j->*isKind)()) {
    wrong(memberPath(path, key), what, *j);
    return nullptr;
  }
  return j;
}

const json* Fields::object(const json& parent, const std::string& path, const std::string& key) {
  return ofKind(parent, path, key, "an object", &json::is_object);
}

const json* Fields::array(const json& parent, const std::string& path, const std::string& key) {
  return ofKind(parent, path, key, "an array", &json::is_array);
}

std::optional<std::string> Fields::string(const json& parent, const std::string& path, const std::string& key) {
  const json* j = get(parent, path, key, "a string");
  if (!j) return std::nullopt;
  if (!j->is_string()) {
    wrong(memberPath(path, key), "a string", *j);
    return std::nullopt;
  }
  return j->get<std::string>();
}

std::optional<std::int64_t> Fields::integer(const json& j, const std::string& path, std::int64_t lo, std::int64_t hi) {
  const bool inRange = (j.is_number_integer() && j.get<std::int64_t>() >= lo && j.get<std::int64_t>() <= hi) ||
                       (j.is_number_unsigned() && j.get<std::uint64_t>() <= static_cast<std::uint64_t>(hi) && lo <= 0);
  if (!inRange) {
    fail(path, "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + describe(j));
    return std::nullopt;
  }
  return j.get<std::int64_t>();
}

std::optional<std::int64_t> Fields::integer(const json& parent, const std::string& path, const std::string& key, std::int64_t lo,
                                            std::int64_t hi) {
  const json* j = get(parent, path, key, "an integer");
  return j ? integer(*j, memberPath(path, key), lo, hi) : std::nullopt;
}

std::optional<std::uint64_t> Fields::count(const json& j, const std::string& path) {
  if (!j.is_number_unsigned() && !(j.is_number_integer() && j.get<std::int64_t>() >= 0)) {
    fail(path, "expected a whole number >= 0, got " + describe(j));
    return std::nullopt;
  }
  return j.get<std::uint64_t>();
}

std::optional<double> Fields::number(const json& parent, const std::string& path, const std::string& key) {
  const json* j = get(parent, path, key, "a number");
  if (!j) return std::nullopt;
  if (!j->is_number() || !std::isfinite(j->get<double>())) {
    wrong(memberPath(path, key), "a finite number", *j);
    return std::nullopt;
  }
  return j->get<double>();
}

std::optional<std::array<double, 3>> Fields::vec3(const json& parent, const std::string& path, const std::string& key) {
  const json* j = get(parent, path, key, "three numbers");
  if (!j) return std::nullopt;
  if (!j->is_array() || j->size() != 3 || !std::all_of(j->begin(), j->end(), [](const json& v) {
        return v.is_number() && std::isfinite(v.get<double>());
      })) {
    wrong(memberPath(path, key), "an array of three finite numbers", *j);
    return std::nullopt;
  }
  return std::array<double, 3>{(*j)[0].get<double>(), (*j)[1].get<double>(), (*j)[2].get<double>()};
}

// `key` must hold exactly `want` (a string).
void Fields::same(const json& parent, const std::string& path, const std::string& key, const std::string& want, const std::string& why) {
  if (const auto got = string(parent, path, key); got && *got != want)
    fail(memberPath(path, key), "expected \"" + printableName(want) + "\" (" + why + "), got " + describe(json(*got)));
}

void Fields::wrong(const std::string& path, const char* what, const json& got) {
  fail(path, std::string("expected ") + what + ", got " + describe(got));
}

}  // namespace manifest_input

}  // namespace rodfab::printer_profiles
