// Reading a design's training: the load cases and their targets (in the "mechanics" block) and the
// "optimize" block (mechanics_reader.hpp).
#include "mechanics/mechanics_reader.hpp"
#include "common/quoted_text.hpp"

#include "common/json_input.hpp"

#include <algorithm>
#include <utility>

namespace rodfab::mechanics::detail {

using geometry::DesignIssue;

// "load_cases": [{name, supports, loads, distributed_loads, load_steps, target, weight}]. The
// supports and loads read as those at the top of the mechanics block (the same code, on a copy
// holding only them); load_steps defaults to the block's.
void MechanicsReader::loadCases(const json& j, const std::string& path, const RodNames& names, MechanicsSpec& spec) {
  if (!j.is_array() || j.empty()) {
    fail(path, "expected a non-empty array of load cases {name, supports, loads, target, weight}, got " + describe(j));
    return;
  }
  // Every case is a solve per optimizer iteration: more than this is no training, and would run for days.
  constexpr std::size_t kMaxLoadCases = 256;
  if (j.size() > kMaxLoadCases) {
    fail(path, "expected at most " + std::to_string(kMaxLoadCases) + " load cases, got " + std::to_string(j.size()));
    return;
  }
  std::map<std::string, std::string> caseNames;
  for (std::size_t i = 0; i < j.size(); ++i) {
    const std::string cp = indexPath(path, i);
    const json& c = j[i];
    if (!c.is_object()) {
      fail(cp, "expected a load case {name, supports, loads, distributed_loads, load_steps, target, weight}, got " + describe(c));
      continue;
    }
    onlyKeys(c, cp, {"name", "supports", "loads", "distributed_loads", "load_steps", "target", "weight"});
    LoadCase lc;
    lc.path = cp;
    if (auto n = require(c, cp, "name", "a case name (a non-empty string)"))
      if (auto name = this->name(*n, memberPath(cp, "name"), "a case name")) {
        lc.name = *name;
        if (auto [it, fresh] = caseNames.emplace(*name, cp); !fresh)
          fail(memberPath(cp, "name"), "duplicate load case name \"" + *name + "\" (also " + it->second + ")");
      }
    json loads = json::object();
    for (const char* key : {"supports", "loads", "distributed_loads", "load_steps"})
      if (auto v = c.find(key); v != c.end()) loads[key] = *v;
    MechanicsSpec caseSpec = mechanics(loads, cp, names);
    lc.supports = std::move(caseSpec.supports);
    lc.loads = std::move(caseSpec.loads);
    lc.distributedLoads = std::move(caseSpec.distributedLoads);
    lc.loadSteps = c.contains("load_steps") ? caseSpec.loadSteps : spec.loadSteps;
    if (auto w = c.find("weight"); w != c.end())
      if (auto x = objectiveWeight(*w, memberPath(cp, "weight"))) lc.weight = *x;
    if (auto t = c.find("target"); t != c.end()) target(*t, memberPath(cp, "target"), names, lc);
    spec.loadCases.push_back(std::move(lc));
  }
  if (spec.loadCases.size() == j.size() &&
      std::all_of(spec.loadCases.begin(), spec.loadCases.end(), [](const LoadCase& lc) { return lc.weight == 0.0; }))
    fail(path, "every load case's weight is 0: the objective would be empty (expected at least one weight > 0)");
}

// "target": {"design": PATH} (read by readDesign, relative to the design file) or
// {"rods": {NAME: {centerline, orientation | normal}}}.
void MechanicsReader::target(const json& j, const std::string& path, const RodNames& names, LoadCase& lc) {
  if (!j.is_object() || j.size() != 1 || !(j.contains("design") || j.contains("rods"))) {
    fail(path, "expected {\"design\": PATH} or {\"rods\": {ROD NAME: {centerline, orientation}}}, got " + describe(j));
    return;
  }
  if (auto d = j.find("design"); d != j.end()) {
    if (auto file = string(*d, memberPath(path, "design"), "a design file's path, relative to this design")) {
      if (file->empty() || common::holdsControlCharacters(*file))
        fail(memberPath(path, "design"), "expected a non-empty path without control characters, got " + common::quotedFromFile(*file));
      else lc.targetDesign = *file;
    }
    return;
  }
  const json& rods = j["rods"];
  const std::string rp = memberPath(path, "rods");
  if (!rods.is_object() || rods.empty()) {
    fail(rp, "expected a non-empty object {ROD NAME: {centerline, orientation}}, got " + describe(rods));
    return;
  }
  for (auto it = rods.begin(); it != rods.end(); ++it) {
    const std::string ep = memberPath(rp, it.key());
    if (!knownRod(it.key(), ep, names)) continue;
    if (auto t = targetRod(*it, ep)) {
      t->rod = it.key();
      lc.target.push_back(std::move(*t));
    }
  }
}

// One target rod: a centerline and optionally its frames ("orientation" or "normal").
std::optional<TargetRod> MechanicsReader::targetRod(const json& j, const std::string& path) {
  if (!j.is_object()) {
    fail(path, "expected a target {centerline, orientation}, got " + describe(j));
    return std::nullopt;
  }
  onlyKeys(j, path, {"centerline", "orientation", "normal"});
  const std::size_t before = issues.size();
  TargetRod t;
  t.path = path;
  std::optional<geometry::NurbsCurve> curve;
  if (auto c = require(j, path, "centerline", "a NURBS curve {degree, knots, points, weights}")) curve = centerline(*c, memberPath(path, "centerline"));
  if (j.contains("orientation") && j.contains("normal")) fail(path, "give either \"normal\" or \"orientation\", not both");
  if (auto o = j.find("orientation"); o != j.end()) t.orientation = orientation(*o, memberPath(path, "orientation"), curve ? &*curve : nullptr);
  if (auto n = j.find("normal"); n != j.end()) t.referenceNormal = referenceNormal(*n, memberPath(path, "normal"), curve ? &*curve : nullptr);
  if (!curve || issues.size() != before) return std::nullopt;
  t.centerline = std::move(*curve);
  return t;
}

// The top-level "optimize" block.
OptimizeSpec MechanicsReader::optimize(const json& j, const std::string& path) {
  OptimizeSpec spec;
  spec.present = true;
  if (!j.is_object()) {
    fail(path, "expected an object {position_weight, curvature_weight, modulus_controls, ...}, got " + describe(j));
    return spec;
  }
  onlyKeys(j, path, {"position_weight", "curvature_weight", "modulus_controls", "modulus_degree", "bounds_mpa",
                     "max_iterations", "tolerance"});
  const auto weight = [&](const char* key, double& out) {
    if (auto v = j.find(key); v != j.end())
      if (auto x = objectiveWeight(*v, memberPath(path, key))) out = *x;
  };
  weight("position_weight", spec.positionWeight);
  weight("curvature_weight", spec.curvatureWeight);
  if (spec.positionWeight == 0 && spec.curvatureWeight == 0)
    fail(path, "position_weight and curvature_weight are both 0: the objective would be empty (expected one of them > 0)");
  const auto integer = [&](const char* key, long long lo, long long hi, int& out) {
    if (auto v = j.find(key); v != j.end()) {
      if (!v->is_number_integer() || v->get<long long>() < lo || v->get<long long>() > hi)
        fail(memberPath(path, key), "expected an integer from " + std::to_string(lo) + " to " + std::to_string(hi) + ", got " + describe(*v));
      else out = v->get<int>();
    }
  };
  integer("modulus_controls", 2, 64, spec.modulusControls);
  integer("modulus_degree", 1, geometry::kMaxDegree, spec.modulusDegree);
  integer("max_iterations", 0, 100000, spec.maxIterations);
  if (auto v = j.find("tolerance"); v != j.end())
    if (auto x = number(*v, memberPath(path, "tolerance"), "a tolerance (a number >= 0)")) {
      if (*x < 0) fail(memberPath(path, "tolerance"), "expected a tolerance >= 0, got " + describe(*v));
      else spec.tolerance = *x;
    }
  if (auto v = j.find("bounds_mpa"); v != j.end()) {
    const std::string bp = memberPath(path, "bounds_mpa");
    if (!v->is_array() || v->size() != 2) {
      fail(bp, "expected [lowest, highest] Young's modulus in MPa, got " + describe(*v));
    } else {
      auto lo = youngsModulus((*v)[0], indexPath(bp, 0)), hi = youngsModulus((*v)[1], indexPath(bp, 1));
      if (lo && hi && !(*lo < *hi)) fail(bp, "expected the lowest modulus below the highest, got " + describe(*v));
      else if (lo && hi) spec.boundsMpa = std::make_pair(*lo, *hi);
    }
  }
  return spec;
}

void resolveTargetDesigns(Design& design, const geometry::RodNames& names, const std::filesystem::path& file) {
  std::vector<DesignIssue> issues;
  for (LoadCase& lc : design.mechanics.loadCases) {
    if (lc.targetDesign.empty()) continue;
    const std::string where = lc.path + ".target.design";
    const std::filesystem::path targetFile = targetDesignFile(lc, file);
    Design target;
    try {
      target = parseDesign(common::readBoundedFile(targetFile.string()), targetFile.string());
    } catch (const common::JsonInputError& e) {
      common::listIssue(issues, DesignIssue{where, "cannot read the target design " + targetFile.string() + ": " + e.message});
      continue;
    } catch (const geometry::DesignError& e) {
      common::listIssue(issues, DesignIssue{where, "the target design is not valid: " + std::string(e.what())});
      continue;
    }
    lc.target.clear();
    for (std::size_t i = 0; i < target.rods.size(); ++i) {
      const geometry::Rod& r = target.rods[i];
      if (!names.contains(r.name())) {
        common::listIssue(issues, DesignIssue{where, targetFile.string() + ": rods[" + std::to_string(i) + "]: the target's rod \"" + r.name() +
                                                          "\" is not in this design (targets match rods by name)"});
        continue;
      }
      lc.target.push_back({r.name(), r.centerline(), r.orientation(), r.referenceNormal(),
                           targetFile.string() + ": rods[" + std::to_string(i) + "]"});
    }
  }
  if (!issues.empty()) throw geometry::DesignError(design.source, std::move(issues));
}

}  // namespace rodfab::mechanics::detail
