// Writing design files: the rods as the format describes them, one per line, written atomically.
#include "geometry/design_writer.hpp"

#include "common/interrupt.hpp"
#include "common/output_file.hpp"

#include <sstream>

namespace rodfab::geometry {

using ordered = nlohmann::ordered_json;

namespace {

ordered curveJson(int degree, const std::vector<double>& knots) { return ordered{{"degree", degree}, {"knots", knots}}; }

}  // namespace

ordered vec3Json(const Vec3& v) { return ordered::array({v.x(), v.y(), v.z()}); }

ordered nurbsJson(const NurbsCurve& c) {
  ordered centerline = curveJson(c.degree(), c.knots());
  ordered points = ordered::array();
  for (const Vec3& p : c.points()) points.push_back({p.x(), p.y(), p.z()});
  centerline["points"] = points;
  if (c.isRational()) centerline["weights"] = c.weights();
  return centerline;
}

ordered quaternionSplineJson(const QuaternionSpline& q) {
  ordered o = curveJson(q.degree(), q.knots());
  ordered quats = ordered::array();
  for (const auto& v : q.quaternions()) quats.push_back({v[0], v[1], v[2], v[3]});
  o["quaternions"] = quats;
  return o;
}

ordered rodJson(const std::string& name, const NurbsCurve& centerline, const Section& section,
                const std::optional<Vec3>& referenceNormal, const std::optional<QuaternionSpline>& orientation, CapStyle caps,
                const BSplineField& modulus) {
  ordered r{{"name", name}, {"centerline", nurbsJson(centerline)}};
  if (section.shape == SectionShape::Circle) r["section"] = {{"shape", "circle"}, {"diameter", section.width}};
  else r["section"] = {{"shape", std::string(toString(section.shape))}, {"width", section.width}, {"height", section.height}};
  if (referenceNormal) r["normal"] = vec3Json(*referenceNormal);
  if (orientation) r["orientation"] = quaternionSplineJson(*orientation);
  if (caps == CapStyle::Flat) r["caps"] = "flat";
  if (modulus.isConstant()) {
    r["modulus"] = modulus.values().front();
  } else {
    ordered m = curveJson(modulus.degree(), modulus.knots());
    m["values"] = modulus.values();
    r["modulus"] = m;
  }
  return r;
}

nlohmann::ordered_json designToJson(const RodStructure& structure, const std::string& description) {
  ordered rods = ordered::array();
  for (const Rod& rod : structure.rods) {
    if (rods.size() % 1024 == 0) common::throwIfInterrupted();  // 30,000 mesh-made rods take a second
    rods.push_back(rodJson(rod.name(), rod.centerline(), rod.section(), rod.referenceNormal(), rod.orientation(), rod.caps(), rod.modulus()));
  }
  return designJson(std::move(rods), description);
}

nlohmann::ordered_json designJson(nlohmann::ordered_json rods, const std::string& description) {
  ordered doc{{"format", kDesignFormat}, {"units", "mm"}};
  if (!description.empty()) doc["description"] = description;
  doc["rods"] = std::move(rods);
  return doc;
}

void writeDesignDocument(const ordered& doc, const std::filesystem::path& file) {
  std::ostringstream out;  // the members after the opening line: sealed below
  for (auto it = doc.begin(); it != doc.end(); ++it) {
    if (it.key() == "rods" || it.key() == "mechanics") continue;
    out << "  " << ordered(it.key()).dump() << ": " << it.value().dump() << ",\n";
  }
  out << "  \"rods\": [\n";
  const auto& rods = doc["rods"];
  for (std::size_t i = 0; i < rods.size(); ++i) {
    if (i % 1024 == 0) common::throwIfInterrupted();
    out << "    " << rods[i].dump() << (i + 1 < rods.size() ? ",\n" : "\n");
  }
  out << "  ]";
  if (auto m = doc.find("mechanics"); m != doc.end()) out << ",\n  \"mechanics\": " << m->dump(2, ' ');
  out << "\n}\n";
  common::writeFileAtomically(file, common::sealJsonObject(out.str()));
}

void writeDesign(const RodStructure& structure, const std::filesystem::path& file, const std::string& description) {
  writeDesignDocument(designToJson(structure, description), file);
}

bool isDesignRodfabWrote(const std::filesystem::path& file) {
  return common::fileStartsWith(file, "{", std::string("\"") + kDesignFormat + "\"", 256) && common::isSealedJsonObject(file);
}

}  // namespace rodfab::geometry
