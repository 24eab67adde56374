// Internal to the manifest readers of `inspect` (inspect_layout.cpp, inspect_manifest_figures.cpp):
// typed access to the untrusted manifest, each failure a finding at "manifest.json: PATH", and the
// readers of the blocks that live in a file of their own.
#pragma once

#include "printer_profiles/inspect_layout.hpp"

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <string>

namespace rodfab::printer_profiles::manifest_input {

using nlohmann::json;

// A short description of an untrusted value, for messages: never serializes containers.
std::string describe(const json& j);

bool nearlyEqual(double a, double b);  // within 1e-9, relative (absolute below 1)

// Typed access to manifest fields; each failure is a finding at "manifest.json: PATH". `path` is where
// `parent` stands (common::memberPath, "" for the top level); every getter returns nothing after a finding.
class Fields {
public:
  explicit Fields(Findings& findings) : findings_(findings) {}

  void fail(const std::string& path, const std::string& message);
  // parent[key], present (`what`: "an integer", ... for the message when it is missing).
  const json* get(const json& parent, const std::string& path, const std::string& key, const char* what);
  // parent[key] when `isKind` holds for it (`what`: "an object", ...).
  const json* ofKind(const json& parent, const std::string& path, const std::string& key, const char* what,
                     bool (json::*isKind)() const noexcept);
  const json* object(const json& parent, const std::string& path, const std::string& key);
  const json* array(const json& parent, const std::string& path, const std::string& key);
  std::optional<std::string> string(const json& parent, const std::string& path, const std::string& key);
  std::optional<std::int64_t> integer(const json& j, const std::string& path, std::int64_t lo, std::int64_t hi);
  std::optional<std::int64_t> integer(const json& parent, const std::string& path, const std::string& key, std::int64_t lo,
                                      std::int64_t hi);
  std::optional<std::uint64_t> count(const json& j, const std::string& path);  // a whole number >= 0
  std::optional<double> number(const json& parent, const std::string& path, const std::string& key);  // finite
  std::optional<std::array<double, 3>> vec3(const json& parent, const std::string& path, const std::string& key);
  // `key` must hold exactly `want` (a string).
  void same(const json& parent, const std::string& path, const std::string& key, const std::string& want, const std::string& why);
  // A finding at `path`: "expected `what`, got" the value described.
  void wrong(const std::string& path, const char* what, const json& got);

private:
  Findings& findings_;
};

// inspect_manifest_figures.cpp: the "frame" block (origin, first indices, part box and size; the size also
// to the summary) and the "statistics" block, into `out` (after its materials are read).
void readFrame(const json& m, JobLayout& out, Fields& f, InspectSummary& s);
void readStatistics(const json& m, JobLayout& out, Fields& f);

}  // namespace rodfab::printer_profiles::manifest_input
