// Reading the "mechanics" and "optimize" blocks of a design file, on top of geometry's reader of
// its rods: the same issue list, so one read reports every violation of the file.
#include "mechanics/mechanics_file.hpp"

#include "common/json_input.hpp"
#include "geometry/design_reader.hpp"

#include <algorithm>
#include <nlohmann/json.hpp>

namespace rodfab::mechanics {

std::filesystem::path targetDesignFile(const LoadCase& loadCase, const std::filesystem::path& designFile) {
  if (loadCase.targetDesign.empty()) return {};
  return designFile.parent_path() / loadCase.targetDesign;  // `/` keeps an absolute PATH as it is
}

using geometry::describe;
using geometry::DesignIssue;
using geometry::indexPath;
using geometry::memberPath;
using geometry::RodNames;
using nlohmann::json;

namespace {

class MechanicsReader : public geometry::DesignReader {
public:
  MechanicsSpec mechanics(const json& j, const std::string& path, const RodNames& names);
  OptimizeSpec optimize(const json& j, const std::string& path);

private:
  // True when a rod is named `name`; false after an issue at `path`.
  bool knownRod(const std::string& name, const std::string& path, const RodNames& names) {
    if (names.count(name)) return true;
    fail(path, "no rod is named \"" + name + "\"");
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

// {"rod", "end"}, {"rod", "parameter"} or {"point"}. The parameter's range is checked by the
// solver, which knows each rod's domain.
std::optional<RodEndRef> MechanicsReader::endRef(const json& j, const std::string& path, const RodNames& names) {
  if (!j.is_object()) {
    fail(path, "expected {\"rod\": NAME, \"end\": \"start\"|\"end\"}, {\"rod\": NAME, \"parameter\": u} or "
               "{\"point\": [x, y, z]}, got " + describe(j));
    return std::nullopt;
  }
  onlyKeys(j, path, {"rod", "end", "parameter", "point"});
  RodEndRef ref;
  ref.path = path;
  const bool byRod = j.contains("rod"), byPoint = j.contains("point");
  if (byRod == byPoint) {
    fail(path, "give either \"rod\" with \"end\" or \"parameter\", or \"point\"");
    return std::nullopt;
  }
  if (byPoint) {
    ref.point = vector3(j["point"], memberPath(path, "point"), "a point in mm");
    for (const char* key : {"end", "parameter"})
      if (j.contains(key)) fail(memberPath(path, key), std::string("\"") + key + "\" goes with \"rod\", not with \"point\"");
    return ref.point ? std::optional<RodEndRef>(ref) : std::nullopt;
  }
  auto name = string(j["rod"], memberPath(path, "rod"), "a rod name");
  if (!name) return std::nullopt;
  if (!knownRod(*name, memberPath(path, "rod"), names)) return std::nullopt;
  ref.rod = *name;
  if (j.contains("parameter")) {
    if (j.contains("end")) {
      fail(path, "give either \"end\" or \"parameter\", not both");
      return std::nullopt;
    }
    ref.parameter = number(j["parameter"], memberPath(path, "parameter"), "a centerline parameter u");
    return ref.parameter ? std::optional<RodEndRef>(ref) : std::nullopt;
  }
  const json* e = require(j, path, "end", "\"start\" or \"end\" (or \"parameter\": u)");
  if (!e) return std::nullopt;
  if (*e == "start") ref.end = RodEnd::Start;
  else if (*e == "end") ref.end = RodEnd::End;
  else {
    fail(memberPath(path, "end"), "expected \"start\" or \"end\", got " + describe(*e));
    return std::nullopt;
  }
  return ref;
}

std::optional<double> MechanicsReader::ratio(const json& j, const std::string& path, const std::string& what, double lo, double hi) {
  auto v = number(j, path, what);
  if (v && !(*v > lo && *v < hi)) {
    fail(path, "expected " + what + " in (" + describe(lo) + ", " + describe(hi) + "), got " + describe(j));
    return std::nullopt;
  }
  return v;
}

MechanicsSpec MechanicsReader::mechanics(const json& j, const std::string& path, const RodNames& names) {
  MechanicsSpec spec;
  spec.present = true;
  if (!j.is_object()) {
    fail(path, "expected an object {poisson_ratio, supports, loads, ...}, got " + describe(j));
    return spec;
  }
  onlyKeys(j, path, {"poisson_ratio", "shear_factor", "joint_tolerance", "joints", "supports", "loads",
                     "distributed_loads", "rods", "load_steps", "load_cases"});
  constants(j, path, spec);
  if (auto v = j.find("joints"); v != j.end()) joints(*v, memberPath(path, "joints"), names, spec);
  list(j, path, "supports", "supports {at, type, displacement, rotation}", spec.supports,
       [&](const json& e, const std::string& ep) { return support(e, ep, names); });
  list(j, path, "loads", "point loads {at, force, moment}", spec.loads,
       [&](const json& e, const std::string& ep) { return pointLoad(e, ep, names); });
  list(j, path, "distributed_loads", "distributed loads {rod, force}", spec.distributedLoads,
       [&](const json& e, const std::string& ep) { return distributedLoad(e, ep, names); });
  if (auto v = j.find("rods"); v != j.end()) rodOverrides(*v, memberPath(path, "rods"), names, spec);
  if (auto v = j.find("load_cases"); v != j.end()) loadCases(*v, memberPath(path, "load_cases"), names, spec);
  return spec;
}

// poisson_ratio, shear_factor, joint_tolerance and load_steps.
void MechanicsReader::constants(const json& j, const std::string& path, MechanicsSpec& spec) {
  if (auto v = j.find("poisson_ratio"); v != j.end())
    if (auto x = ratio(*v, memberPath(path, "poisson_ratio"), "a Poisson ratio", -1.0, 0.5)) spec.poissonRatio = *x;
  if (auto v = j.find("shear_factor"); v != j.end())
    spec.shearFactor = positive(*v, memberPath(path, "shear_factor"), "a shear correction factor");
  if (auto v = j.find("joint_tolerance"); v != j.end())
    if (auto x = positive(*v, memberPath(path, "joint_tolerance"), "a distance in mm")) spec.jointTolerance = *x;
  if (auto v = j.find("load_steps"); v != j.end()) {
    if (!v->is_number_integer() || v->get<long long>() < 1 || v->get<long long>() > kMaxLoadSteps)
      fail(memberPath(path, "load_steps"), "expected an integer from 1 to " + std::to_string(kMaxLoadSteps) + ", got " + describe(*v));
    else
      spec.loadSteps = v->get<int>();
  }
}

// "joints": "auto" or an array of joints, each an array of at least two rod ends or rod points.
void MechanicsReader::joints(const json& j, const std::string& jp, const RodNames& names, MechanicsSpec& spec) {
  if (j == "auto") {
    spec.inferJoints = true;
    return;
  }
  if (!j.is_array()) {
    fail(jp, "expected \"auto\" (join coincident rod ends) or an array of joints, each an array of rod ends, got " +
                 describe(j));
    return;
  }
  spec.inferJoints = false;
  for (std::size_t i = 0; i < j.size(); ++i) {
    const json& joint = j[i];
    const std::string ip = indexPath(jp, i);
    if (!joint.is_array() || joint.size() < 2) {
      fail(ip, "expected an array of at least two rod ends {\"rod\", \"end\"}, got " + describe(joint));
      continue;
    }
    std::vector<RodEndRef> ends;
    for (std::size_t k = 0; k < joint.size(); ++k) {
      auto ref = endRef(joint[k], indexPath(ip, k), names);
      if (ref && ref->point)
        fail(indexPath(ip, k), "joints list rod ends {\"rod\", \"end\"} or rod points {\"rod\", \"parameter\"}, not points");
      else if (ref) ends.push_back(*ref);
    }
    spec.joints.push_back(std::move(ends));
  }
}

std::optional<Support> MechanicsReader::support(const json& e, const std::string& ep, const RodNames& names) {
  onlyKeys(e, ep, {"at", "type", "displacement", "rotation"});
  Support s;
  std::optional<RodEndRef> at;
  if (auto a = require(e, ep, "at", "a place {\"rod\", \"end\"}, {\"rod\", \"parameter\"} or {\"point\"}")) at = endRef(*a, memberPath(ep, "at"), names);
  if (auto t = require(e, ep, "type", "\"clamped\" or \"pinned\"")) {
    if (*t == "clamped") s.kind = SupportKind::Clamped;
    else if (*t == "pinned") s.kind = SupportKind::Pinned;
    else fail(memberPath(ep, "type"), "expected \"clamped\" (position and orientation held) or \"pinned\" (position held), got " + describe(*t));
  }
  if (auto d = e.find("displacement"); d != e.end()) {
    if (auto v = vector3(*d, memberPath(ep, "displacement"), "a displacement in mm")) s.displacement = *v;
  }
  if (auto r = e.find("rotation"); r != e.end()) {
    if (s.kind == SupportKind::Pinned) fail(memberPath(ep, "rotation"), "a pinned support leaves rotation free; use \"type\": \"clamped\" to prescribe it");
    else if (auto v = vector3(*r, memberPath(ep, "rotation"), "a rotation vector (axis times angle, radians)")) s.rotation = *v;
  }
  if (!at) return std::nullopt;
  s.at = *at;
  return s;
}

std::optional<PointLoad> MechanicsReader::pointLoad(const json& e, const std::string& ep, const RodNames& names) {
  onlyKeys(e, ep, {"at", "force", "moment", "follower"});
  PointLoad l;
  std::optional<RodEndRef> at;
  if (auto a = require(e, ep, "at", "a place {\"rod\", \"end\"}, {\"rod\", \"parameter\"} or {\"point\"}")) at = endRef(*a, memberPath(ep, "at"), names);
  bool ok = true;
  if (auto f = e.find("force"); f != e.end()) {
    if (auto v = vector3(*f, memberPath(ep, "force"), "a force in N")) l.force = *v; else ok = false;
  }
  if (auto m = e.find("moment"); m != e.end()) {
    if (auto v = vector3(*m, memberPath(ep, "moment"), "a moment in N mm")) l.moment = *v; else ok = false;
  }
  if (auto f = e.find("follower"); f != e.end()) {
    if (f->is_boolean()) l.follower = f->get<bool>();
    else fail(memberPath(ep, "follower"), "expected true (the load turns with the cross-section) or false (a dead load), got " + describe(*f)), ok = false;
  }
  if (!e.contains("force") && !e.contains("moment")) fail(ep, "a load needs \"force\" (N) or \"moment\" (N mm)"), ok = false;
  if (!at || !ok) return std::nullopt;
  l.at = *at;
  return l;
}

std::optional<DistributedLoad> MechanicsReader::distributedLoad(const json& e, const std::string& ep, const RodNames& names) {
  onlyKeys(e, ep, {"rod", "force"});
  DistributedLoad l;
  l.path = ep;
  std::optional<std::string> rod;
  if (auto r = require(e, ep, "rod", "a rod name")) {
    rod = string(*r, memberPath(ep, "rod"), "a rod name");
    if (rod && !knownRod(*rod, memberPath(ep, "rod"), names)) rod.reset();
  }
  std::optional<geometry::Vec3> f;
  if (auto x = require(e, ep, "force", "a force per length in N/mm")) f = vector3(*x, memberPath(ep, "force"), "a force per length in N/mm");
  if (!rod || !f) return std::nullopt;
  l.rod = *rod;
  l.force = *f;
  return l;
}

// "rods": {ROD NAME: {torsion_constant, shear_factor, poisson_ratio}}.
void MechanicsReader::rodOverrides(const json& j, const std::string& rp, const RodNames& names, MechanicsSpec& spec) {
  if (!j.is_object()) {
    fail(rp, "expected an object {ROD NAME: {torsion_constant, shear_factor, poisson_ratio}}, got " + describe(j));
    return;
  }
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string ep = memberPath(rp, it.key());
    if (!knownRod(it.key(), ep, names)) continue;
    if (!it->is_object()) {
      fail(ep, "expected an object {torsion_constant, shear_factor, poisson_ratio}, got " + describe(*it));
      continue;
    }
    onlyKeys(*it, ep, {"torsion_constant", "shear_factor", "poisson_ratio"});
    RodMechanics m;
    m.rod = it.key();
    if (auto x = it->find("torsion_constant"); x != it->end())
      m.torsionConstant = positive(*x, memberPath(ep, "torsion_constant"), "a torsion constant in mm^4");
    if (auto x = it->find("shear_factor"); x != it->end())
      m.shearFactor = positive(*x, memberPath(ep, "shear_factor"), "a shear correction factor");
    if (auto x = it->find("poisson_ratio"); x != it->end())
      m.poissonRatio = ratio(*x, memberPath(ep, "poisson_ratio"), "a Poisson ratio", -1.0, 0.5);
    spec.rods.push_back(std::move(m));
  }
}

// ---- design optimization: training cases, targets and the "optimize" block ----

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
      if (auto name = string(*n, memberPath(cp, "name"), "a case name")) {
        lc.name = *name;
        if (name->empty()) fail(memberPath(cp, "name"), "expected a non-empty case name");
        else if (auto [it, fresh] = caseNames.emplace(*name, cp); !fresh)
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
      if (auto x = number(*w, memberPath(cp, "weight"), "a weight (a number >= 0)")) {
        if (*x < 0) fail(memberPath(cp, "weight"), "expected a weight >= 0, got " + describe(*w));
        else lc.weight = *x;
      }
    if (auto t = c.find("target"); t != c.end()) target(*t, memberPath(cp, "target"), names, lc);
    spec.loadCases.push_back(std::move(lc));
  }
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
      if (file->empty()) fail(memberPath(path, "design"), "expected a non-empty path");
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
  if (auto n = j.find("normal"); n != j.end()) {
    t.referenceNormal = vector3(*n, memberPath(path, "normal"), "a reference normal");
    if (t.referenceNormal && !(t.referenceNormal->cwiseAbs().maxCoeff() > 0.0)) fail(memberPath(path, "normal"), "the reference normal must not be zero");
  }
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
      if (auto x = number(*v, memberPath(path, key), "a weight (a number >= 0)")) {
        if (*x < 0) fail(memberPath(path, key), "expected a weight >= 0, got " + describe(*v));
        else out = *x;
      }
  };
  weight("position_weight", spec.positionWeight);
  weight("curvature_weight", spec.curvatureWeight);
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
// The rods of a load case's {"design": PATH} target: the rods of that design (its own targets are
// not followed) that carry names of this one.
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
      issues.push_back({where, "cannot read the target design " + targetFile.string() + ": " + e.message});
      continue;
    } catch (const geometry::DesignError& e) {
      issues.push_back({where, "the target design is not valid: " + std::string(e.what())});
      continue;
    }
    lc.target.clear();
    for (std::size_t i = 0; i < target.rods.size(); ++i) {
      const geometry::Rod& r = target.rods[i];
      if (!names.contains(r.name())) {
        issues.push_back({where, targetFile.string() + ": rods[" + std::to_string(i) + "]: the target's rod \"" + r.name() +
                                     "\" is not in this design (targets match rods by name)"});
        continue;
      }
      lc.target.push_back({r.name(), r.centerline(), r.orientation(), r.referenceNormal(),
                           targetFile.string() + ": rods[" + std::to_string(i) + "]"});
    }
  }
  if (!issues.empty()) throw geometry::DesignError(design.source, std::move(issues));
}

}  // namespace

namespace {

// A design read with its blocks (its rods kept or only summarized), and the names of its rods.
struct ReadDesign {
  Design design;
  geometry::DesignSummary summary;
  geometry::RodNames names;
};

ReadDesign parseWithBlocks(const std::string& text, const std::string& sourceName, geometry::RodsKept kept) {
  MechanicsReader reader;
  geometry::DesignDocument document = geometry::parseDesignDocument(text, sourceName, reader, kept);
  ReadDesign out{Design(std::move(document.structure)), document.summary, std::move(document.rodNames)};
  const json& doc = document.json;
  if (auto m = doc.find("mechanics"); m != doc.end() && document.rodsListed)
    out.design.mechanics = reader.mechanics(*m, "mechanics", out.names);
  if (auto o = doc.find("optimize"); o != doc.end()) out.design.optimize = reader.optimize(*o, "optimize");
  if (!reader.issues.empty()) throw geometry::DesignError(sourceName, std::move(reader.issues));
  return out;
}

ReadDesign readWithTargets(const std::filesystem::path& file, geometry::RodsKept kept) {
  ReadDesign read = parseWithBlocks(geometry::readDesignText(file), file.string(), kept);
  resolveTargetDesigns(read.design, read.names, file);
  return read;
}

}  // namespace

Design parseDesign(const std::string& text, const std::string& sourceName) {
  return parseWithBlocks(text, sourceName, geometry::RodsKept::All).design;
}

Design readDesign(const std::filesystem::path& file) { return readWithTargets(file, geometry::RodsKept::All).design; }

geometry::DesignSummary checkDesign(const std::filesystem::path& file) {
  return readWithTargets(file, geometry::RodsKept::SummaryOnly).summary;
}

}  // namespace rodfab::mechanics
