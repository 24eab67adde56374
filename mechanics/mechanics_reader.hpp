// Internal to mechanics/ (mechanics_reader.cpp, optimize_reader.cpp): the reader of a design file's
// "mechanics" and "optimize" blocks, on top of geometry's reader of its rods, so one read reports every
// violation of the file in one issue list.
#pragma once

#include "common/quoted_text.hpp"

#include "mechanics/mechanics_file.hpp"

#include "geometry/design_reader.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace rodfab::mechanics::detail {

using geometry::describe;
using geometry::indexPath;
using geometry::memberPath;
using geometry::RodNames;
using nlohmann::json;

class MechanicsReader : public geometry::DesignReader {
public:
  MechanicsSpec mechanics(const json& j, const std::string& path, const RodNames& names);
  OptimizeSpec optimize(const json& j, const std::string& path);

private:
  // An objective weight: 0, or from kMinObjectiveWeight to kMaxObjectiveWeight (relative weights: a
  // denormal or 1e308 passed the reader and failed inside the optimizer, naming no field).
  std::optional<double> objectiveWeight(const json& j, const std::string& path) {
    const std::optional<double> x = number(j, path, "a weight (a number >= 0)");
    if (x && (*x == 0 || (*x >= kMinObjectiveWeight && *x <= kMaxObjectiveWeight))) return x;
    if (x) fail(path, "expected a weight of 0 or from 1e-06 to 1e+06, got " + describe(j));
    return std::nullopt;
  }
  static constexpr double kMinObjectiveWeight = 1e-6, kMaxObjectiveWeight = 1e6;
  // True when a rod is named `name`; false after an issue at `path`.
  bool knownRod(const std::string& name, const std::string& path, const RodNames& names) {
    if (names.count(name)) return true;
    fail(path, "no rod is named " + common::quotedFromFile(name, 64));
    return false;
  }
  // {"rod", "end"}, {"rod", "parameter"} or {"point"}. The parameter's range is checked by the
  // solver, which knows each rod's domain.
  std::optional<RodEndRef> endRef(const json& j, const std::string& path, const RodNames& names);
  std::optional<double> ratio(const json& j, const std::string& path, const std::string& what, double lo, double hi);
  void constants(const json& j, const std::string& path, MechanicsSpec& spec);
  void joints(const json& j, const std::string& path, const RodNames& names, MechanicsSpec& spec);
  std::optional<Support> support(const json& e, const std::string& path, const RodNames& names);
  std::optional<PointLoad> pointLoad(const json& e, const std::string& path, const RodNames& names);
  std::optional<DistributedLoad> distributedLoad(const json& e, const std::string& path, const RodNames& names);
  void rodOverrides(const json& j, const std::string& path, const RodNames& names, MechanicsSpec& spec);
  void loadCases(const json& j, const std::string& path, const RodNames& names, MechanicsSpec& spec);
  void target(const json& j, const std::string& path, const RodNames& names, LoadCase& lc);
  std::optional<TargetRod> targetRod(const json& j, const std::string& path);

  // The array obj[key] of objects, each read by readItem(element, its path) into `out`.
  template <class Item, class ReadItem>
  void list(const json& obj, const std::string& path, const std::string& key, const std::string& what,
            std::vector<Item>& out, ReadItem readItem) {
    auto it = obj.find(key);
    if (it == obj.end()) return;
    const std::string lp = memberPath(path, key);
    if (!it->is_array()) {
      fail(lp, "expected an array of " + what + ", got " + describe(*it));
      return;
    }
    for (std::size_t i = 0; i < it->size(); ++i) {
      const json& e = (*it)[i];
      const std::string ep = indexPath(lp, i);
      if (!e.is_object()) {
        fail(ep, "expected " + what + " (an object), got " + describe(e));
        continue;
      }
      if (auto item = readItem(e, ep)) out.push_back(std::move(*item));
    }
  }
};

// Replaces each load case's {"design": PATH} target by the rods of that design (its own targets are
// not followed) that carry names of this one (`names`); throws DesignError naming `design.source`
// with every target that cannot be read or names a rod this design lacks.
void resolveTargetDesigns(Design& design, const RodNames& names, const std::filesystem::path& file);

}  // namespace rodfab::mechanics::detail
