// Reading a design file with its "mechanics" block (supports, loads, joints, constants, rod overrides)
// and the entry points that read a whole design; the training (load cases, targets) and the "optimize"
// block are read in optimize_reader.cpp (mechanics_reader.hpp).
#include "mechanics/mechanics_reader.hpp"
#include "mechanics/mechanics.hpp"

#include "common/json_input.hpp"

#include <algorithm>

namespace rodfab::mechanics {

std::filesystem::path targetDesignFile(const LoadCase& loadCase, const std::filesystem::path& designFile) {
  if (loadCase.targetDesign.empty()) return {};
  return designFile.parent_path() / loadCase.targetDesign;  // `/` keeps an absolute PATH as it is
}

namespace detail {

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
  auto name = this->name(j["rod"], memberPath(path, "rod"), "a rod name");
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
    rod = name(*r, memberPath(ep, "rod"), "a rod name");
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

}  // namespace detail

namespace {

// A design read with its blocks (its rods kept or only summarized), and the names of its rods.
struct ReadDesign {
  Design design;
  geometry::DesignSummary summary;
  geometry::RodNames names;
};

ReadDesign parseWithBlocks(const std::string& text, const std::string& sourceName, geometry::RodsKept kept) {
  detail::MechanicsReader reader;
  geometry::DesignDocument document = geometry::parseDesignDocument(text, sourceName, reader, kept);
  ReadDesign out{Design(std::move(document.structure)), document.summary, std::move(document.rodNames)};
  const nlohmann::json& doc = document.json;
  if (auto m = doc.find("mechanics"); m != doc.end() && document.rodsListed)
    out.design.mechanics = reader.mechanics(*m, "mechanics", out.names);
  if (auto o = doc.find("optimize"); o != doc.end()) out.design.optimize = reader.optimize(*o, "optimize");
  if (!reader.issues.empty()) throw geometry::DesignError(sourceName, std::move(reader.issues));
  return out;
}

ReadDesign readWithTargets(const std::filesystem::path& file, geometry::RodsKept kept) {
  ReadDesign read = parseWithBlocks(geometry::readDesignText(file), file.string(), kept);
  detail::resolveTargetDesigns(read.design, read.names, file);
  return read;
}

}  // namespace

Design parseDesign(const std::string& text, const std::string& sourceName) {
  return parseWithBlocks(text, sourceName, geometry::RodsKept::All).design;
}

Design readDesign(const std::filesystem::path& file) { return readWithTargets(file, geometry::RodsKept::All).design; }

geometry::DesignSummary checkDesign(const std::filesystem::path& file) {
  const ReadDesign read = readWithTargets(file, geometry::RodsKept::SummaryOnly);
  if (read.design.mechanics.present) checkMechanics(readDesign(file));  // its rods are needed now
  return read.summary;
}

}  // namespace rodfab::mechanics
