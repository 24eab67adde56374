// Shared by the tests of the design file's readers (tests/test_design_file.cpp for the rods,
// tests/test_mechanics_file.cpp for the mechanics and optimize blocks): a valid one-rod design and
// the issues a reader reports for a bad one.
#pragma once

#include "geometry/design_file.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace rodfab::test {

// The design of the format description: one cubic NURBS rod with a piecewise-linear modulus.
inline nlohmann::json validDesign() {
  return nlohmann::json::parse(R"({ "format": "rodfab.design/1", "units": "mm",
    "rods": [ { "name": "edge-0",
      "centerline": { "degree": 3, "knots": [0,0,0,0,1,1,1,1],
                      "points": [[0,0,0],[1,0,0],[2,1,0],[3,1,0]], "weights": [1,1,1,1] },
      "section": { "shape": "circle", "diameter": 1.5 },
      "normal": [0,0,1],
      "modulus": { "degree": 1, "knots": [0,0,0.5,1,1], "values": [8, 120, 40] } } ] })");
}

// `parse`(text, "bad.json") expecting a DesignError for bad.json; returns its issues.
template <class Parse>
std::vector<geometry::DesignIssue> designIssues(Parse parse, const std::string& text) {
  try {
    parse(text, "bad.json");
  } catch (const geometry::DesignError& e) {
    REQUIRE(e.file() == "bad.json");
    return e.issues();
  }
  FAIL("expected a DesignError");
  return {};
}

inline bool hasIssue(const std::vector<geometry::DesignIssue>& issues, const std::string& path, const std::string& fragment) {
  for (const auto& i : issues)
    if (i.path == path && i.message.find(fragment) != std::string::npos) return true;
  return false;
}

}  // namespace rodfab::test

// Requires an issue at `path` whose message holds `fragment`, from the issuesOf(doc) of the including file.
#define REQUIRE_ISSUE(doc, path, fragment)                                       \
  do {                                                                           \
    const auto issues_ = issuesOf(doc);                                          \
    INFO(::rodfab::geometry::DesignError("bad.json", issues_).what());           \
    REQUIRE(::rodfab::test::hasIssue(issues_, path, fragment));                  \
  } while (0)
