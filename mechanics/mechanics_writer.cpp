// Writing the "mechanics" and "optimize" blocks of a design file, after geometry's rods.
#include "mechanics/mechanics_file.hpp"

#include "geometry/design_writer.hpp"

#include <nlohmann/json.hpp>

namespace rodfab::mechanics {

using geometry::nurbsJson;
using geometry::quaternionSplineJson;
using geometry::vec3Json;
using ordered = nlohmann::ordered_json;

namespace {

ordered endRefJson(const RodEndRef& ref) {
  if (ref.point) return ordered{{"point", vec3Json(*ref.point)}};
  if (ref.parameter) return ordered{{"rod", ref.rod}, {"parameter", *ref.parameter}};
  return ordered{{"rod", ref.rod}, {"end", ref.end == RodEnd::Start ? "start" : "end"}};
}

ordered mechanicsJson(const MechanicsSpec& spec);

// The load cases as read: supports and loads written as at the top of the block, the target as
// given (its design file's path, or the rods inline).
ordered loadCasesJson(const MechanicsSpec& spec) {
  ordered cases = ordered::array();
  for (const LoadCase& lc : spec.loadCases) {
    MechanicsSpec loads;
    loads.supports = lc.supports, loads.loads = lc.loads, loads.distributedLoads = lc.distributedLoads;
    const ordered m = mechanicsJson(loads);
    ordered c{{"name", lc.name}, {"supports", m["supports"]}, {"loads", m["loads"]}};
    if (m.contains("distributed_loads")) c["distributed_loads"] = m["distributed_loads"];
    c["load_steps"] = lc.loadSteps;
    if (!lc.targetDesign.empty()) {
      c["target"] = {{"design", lc.targetDesign}};
    } else if (!lc.target.empty()) {
      ordered rods = ordered::object();
      for (const TargetRod& t : lc.target) {
        ordered r{{"centerline", nurbsJson(t.centerline)}};
        if (t.orientation) r["orientation"] = quaternionSplineJson(*t.orientation);
        if (t.referenceNormal) r["normal"] = vec3Json(*t.referenceNormal);
        rods[t.rod] = r;
      }
      c["target"] = {{"rods", rods}};
    }
    c["weight"] = lc.weight;
    cases.push_back(c);
  }
  return cases;
}

ordered mechanicsJson(const MechanicsSpec& spec) {
  ordered m{{"poisson_ratio", spec.poissonRatio}};
  if (spec.shearFactor) m["shear_factor"] = *spec.shearFactor;
  m["joint_tolerance"] = spec.jointTolerance;
  if (spec.inferJoints) {
    m["joints"] = "auto";
  } else {
    ordered joints = ordered::array();
    for (const auto& joint : spec.joints) {
      ordered ends = ordered::array();
      for (const RodEndRef& e : joint) ends.push_back(endRefJson(e));
      joints.push_back(ends);
    }
    m["joints"] = joints;
  }
  ordered supports = ordered::array();
  for (const Support& s : spec.supports) {
    ordered o{{"at", endRefJson(s.at)}, {"type", s.kind == SupportKind::Clamped ? "clamped" : "pinned"}};
    if (!s.displacement.isZero()) o["displacement"] = vec3Json(s.displacement);
    if (!s.rotation.isZero()) o["rotation"] = vec3Json(s.rotation);
    supports.push_back(o);
  }
  m["supports"] = supports;
  ordered loads = ordered::array();
  for (const PointLoad& l : spec.loads) {
    ordered o{{"at", endRefJson(l.at)}, {"force", vec3Json(l.force)}, {"moment", vec3Json(l.moment)}};
    if (l.follower) o["follower"] = true;
    loads.push_back(o);
  }
  m["loads"] = loads;
  if (!spec.distributedLoads.empty()) {
    ordered d = ordered::array();
    for (const DistributedLoad& l : spec.distributedLoads) d.push_back({{"rod", l.rod}, {"force", vec3Json(l.force)}});
    m["distributed_loads"] = d;
  }
  if (!spec.rods.empty()) {
    ordered rods = ordered::object();
    for (const RodMechanics& r : spec.rods) {
      ordered o = ordered::object();
      if (r.torsionConstant) o["torsion_constant"] = *r.torsionConstant;
      if (r.shearFactor) o["shear_factor"] = *r.shearFactor;
      if (r.poissonRatio) o["poisson_ratio"] = *r.poissonRatio;
      rods[r.rod] = o;
    }
    m["rods"] = rods;
  }
  m["load_steps"] = spec.loadSteps;
  if (!spec.loadCases.empty()) m["load_cases"] = loadCasesJson(spec);
  return m;
}

ordered optimizeJson(const OptimizeSpec& spec) {
  ordered o{{"position_weight", spec.positionWeight}, {"curvature_weight", spec.curvatureWeight},
            {"modulus_controls", spec.modulusControls}, {"modulus_degree", spec.modulusDegree}};
  if (spec.boundsMpa) o["bounds_mpa"] = ordered::array({spec.boundsMpa->first, spec.boundsMpa->second});
  o["max_iterations"] = spec.maxIterations;
  o["tolerance"] = spec.tolerance;
  return o;
}

}  // namespace

nlohmann::ordered_json designToJson(const Design& design, const std::string& description) {
  ordered doc = geometry::designToJson(design, description);
  if (design.mechanics.present) doc["mechanics"] = mechanicsJson(design.mechanics);
  if (design.optimize.present) doc["optimize"] = optimizeJson(design.optimize);
  return doc;
}

void writeDesign(const Design& design, const std::filesystem::path& file, const std::string& description) {
  geometry::writeDesignDocument(designToJson(design, description), file);
}

}  // namespace rodfab::mechanics
