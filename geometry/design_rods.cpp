// Reading the rods of a design file: centerline, section, orientation, modulus field and the rod
// itself, each checked against the format and the others (a field's domain is its centerline's), every
// violation recorded at its JSON path (geometry/design_reader.hpp). The values they are made of and
// the document are read in design_reader.cpp.
#include "geometry/design_reader.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace rodfab::geometry {

using nlohmann::json;

namespace {

bool sameDomain(double a0, double a1, double b0, double b1) {
  const double tol = 1e-9 * std::max({1.0, std::abs(a0), std::abs(a1)});
  return std::abs(a0 - b0) <= tol && std::abs(a1 - b1) <= tol;
}

// True when there is no centerline or [begin, end] is its parameter domain; else an issue at `knotsPath`.
bool domainMatches(DesignReader& reader, double begin, double end, const NurbsCurve* curve, const std::string& knotsPath) {
  if (!curve || sameDomain(begin, end, curve->domainBegin(), curve->domainEnd())) return true;
  reader.fail(knotsPath, "parameter domain [" + std::to_string(begin) + ", " + std::to_string(end) + "] must equal the centerline's [" +
                             std::to_string(curve->domainBegin()) + ", " + std::to_string(curve->domainEnd()) + "]");
  return false;
}

// False, after an issue at `path`, when `count` controls (WHAT) are too few for a spline of degree p.
bool enoughControls(DesignReader& reader, std::optional<int> p, std::size_t count, const std::string& path, const std::string& what) {
  if (!p || count >= static_cast<std::size_t>(*p) + 1) return true;
  reader.fail(path, "degree " + std::to_string(*p) + " needs at least " + std::to_string(*p + 1) + " " + what + ", got " +
                        std::to_string(count));
  return false;
}

// The "knots" of the spline object `j` for degree p and `count` controls (each as far as it was read).
std::optional<std::vector<double>> splineKnots(DesignReader& reader, const json& j, const std::string& path, std::optional<int> p,
                                               std::optional<std::size_t> count) {
  const json* kn = reader.require(j, path, "knots", "an array of knot values");
  if (!kn) return std::nullopt;
  return reader.knots(*kn, memberPath(path, "knots"), p, count);
}

// The elements of the array `j` at `path`, each read by `readElement(element, elementPath)` (an
// std::optional<T>); nullopt after an issue "expected WHAT" when `j` is not an array, or when any
// element failed (every element is still read, so each one's issues are recorded).
template <class T, class ReadElement>
std::optional<std::vector<T>> readArray(DesignReader& reader, const json& j, const std::string& path, const std::string& what,
                                        ReadElement readElement) {
  if (!j.is_array()) {
    reader.fail(path, "expected " + what + ", got " + describe(j));
    return std::nullopt;
  }
  std::vector<T> out;
  bool ok = true;
  for (std::size_t i = 0; i < j.size(); ++i) {
    std::optional<T> element = readElement(j[i], indexPath(path, i));
    if (element) out.push_back(*std::move(element)); else ok = false;
  }
  return ok ? std::optional<std::vector<T>>(std::move(out)) : std::nullopt;
}

// A B-spline's degree, control values and knots, read together.
template <class T>
struct SplineParts {
  int degree = 0;
  std::vector<T> controls;
  std::vector<double> knots;
};

// The {degree, knots, KEY} members of the spline object `j`, the controls under KEY read one by one by
// `readControl`; nullopt unless all three are valid together (every issue is recorded either way).
template <class T, class ReadControl>
std::optional<SplineParts<T>> splineParts(DesignReader& reader, const json& j, const std::string& path, const std::string& key,
                                          const std::string& what, ReadControl readControl) {
  std::optional<int> p;
  if (auto d = reader.require(j, path, "degree", "an integer degree")) p = reader.degree(*d, memberPath(path, "degree"));
  std::optional<std::vector<T>> controls;
  if (auto c = reader.require(j, path, key, what)) {
    const std::string cp = memberPath(path, key);
    if (c->is_array() && c->size() > kMaxSplineControls)
      reader.fail(cp, "expected at most " + std::to_string(kMaxSplineControls) + " " + key + " in one spline, got " +
                          std::to_string(c->size()) + "; split the rod into shorter rods");
    else
      controls = readArray<T>(reader, *c, cp, what, readControl);
    if (controls && !enoughControls(reader, p, controls->size(), cp, key)) controls.reset();
  }
  const std::optional<std::vector<double>> k =
      splineKnots(reader, j, path, p, controls ? std::optional<std::size_t>(controls->size()) : std::nullopt);
  if (!p || !controls || !k) return std::nullopt;
  return SplineParts<T>{*p, std::move(*controls), *k};
}

}  // namespace

std::optional<NurbsCurve> DesignReader::centerline(const json& j, const std::string& path, CenterlineLength length) {
  if (!j.is_object()) {
    fail(path, "expected an object {degree, knots, points, weights}, got " + describe(j));
    return std::nullopt;
  }
  onlyKeys(j, path, {"degree", "knots", "points", "weights"});
  auto parts = splineParts<Vec3>(*this, j, path, "points", "an array of [x, y, z] control points", [&](const json& e, const std::string& ep) {
    std::optional<Vec3> c = vector3(e, ep, "a control point");
    if (c && !(c->cwiseAbs().maxCoeff() <= kMaxCoordinateMm)) {
      fail(ep, "expected coordinates within +-1e9 mm (designs are in millimetres), got " + describe(e));
      c.reset();
    }
    return c;
  });
  std::optional<std::vector<double>> weights = std::vector<double>{};  // none given: a polynomial curve
  if (auto w = j.find("weights"); w != j.end()) {
    const std::string wp = memberPath(path, "weights");
    weights = readArray<double>(*this, *w, wp, "an array of positive weights",
                                [&](const json& e, const std::string& ep) { return positive(e, ep, "a weight"); });
    if (weights && parts && weights->size() != parts->controls.size()) {
      fail(wp, "expected one weight per control point (" + std::to_string(parts->controls.size()) + "), got " +
                   std::to_string(weights->size()));
      weights.reset();
    }
  }
  if (!parts || !weights) return std::nullopt;
  const std::vector<Vec3>& points = parts->controls;
  NurbsCurve curve(parts->degree, parts->knots, points, *weights);
  if (length == CenterlineLength::LeftToRod) return curve;
  try {
    Rod::checkedLength(curve);
  } catch (const CenterlineError& e) {
    fail(path, e.what());
    return std::nullopt;
  }
  return curve;
}

std::optional<double> DesignReader::sectionSize(const json& j, const std::string& path, const std::string& what) {
  auto v = positive(j, path, what);
  static_assert(kMaxSectionMm == 1e6, "the message below says 1e6");
  if (v && !(*v <= kMaxSectionMm)) {
    fail(path, "expected " + what + " of at most 1e6 (a kilometre), got " + describe(j));
    return std::nullopt;
  }
  return v;
}

std::optional<Section> DesignReader::section(const json& j, const std::string& path) {
  if (!j.is_object()) {
    fail(path, "expected an object {shape, ...}, got " + describe(j));
    return std::nullopt;
  }
  const json* shape = require(j, path, "shape", "\"circle\", \"ellipse\" or \"rectangle\"");
  if (!shape) return std::nullopt;
  auto name = string(*shape, memberPath(path, "shape"), "the section shape");
  if (!name) return std::nullopt;
  if (*name == "circle") {
    onlyKeys(j, path, {"shape", "diameter"});
    const json* d = require(j, path, "diameter", "the diameter in mm");
    if (!d) return std::nullopt;
    auto v = sectionSize(*d, memberPath(path, "diameter"), "a diameter in mm");
    return v ? std::optional<Section>(Section::circle(*v)) : std::nullopt;
  }
  if (*name == "ellipse" || *name == "rectangle") {
    onlyKeys(j, path, {"shape", "width", "height"});
    std::optional<double> w, h;
    if (auto x = require(j, path, "width", "the width along d1 in mm")) w = sectionSize(*x, memberPath(path, "width"), "a width in mm");
    if (auto x = require(j, path, "height", "the height along d2 in mm")) h = sectionSize(*x, memberPath(path, "height"), "a height in mm");
    if (!w || !h) return std::nullopt;
    return *name == "ellipse" ? Section::ellipse(*w, *h) : Section::rectangle(*w, *h);
  }
  fail(memberPath(path, "shape"), "unknown section shape " + describe(*shape) + " (expected \"circle\", \"ellipse\" or \"rectangle\")");
  return std::nullopt;
}

std::optional<Vec3> DesignReader::referenceNormal(const nlohmann::json& j, const std::string& path, const NurbsCurve* curve) {
  std::optional<Vec3> normal = vector3(j, path, "a reference normal");
  if (normal && !(normal->cwiseAbs().maxCoeff() > 0.0)) {
    fail(path, "the reference normal must not be zero");
    return std::nullopt;
  }
  if (!normal || !curve) return normal;
  Vec3 d[3];
  curve->derivatives(curve->domainBegin(), 2, d);
  const Vec3 t = unitTangent(d[1], d[2]);
  if (scaledToUnitOrder(*normal).normalized().cross(t).norm() < 1e-6) {  // scaled: 1e300 does not overflow, 1e-320 not underflow
    fail(path, "the reference normal " + describe(j) + " is parallel to the centerline's tangent at its start; "
               "expected a direction across the rod");
    return std::nullopt;
  }
  return normal;
}

std::optional<QuaternionSpline> DesignReader::orientation(const json& j, const std::string& path, const NurbsCurve* curve) {
  if (!j.is_object()) {
    fail(path, "expected an object {degree, knots, quaternions}, got " + describe(j));
    return std::nullopt;
  }
  onlyKeys(j, path, {"degree", "knots", "quaternions"});
  const auto parts = splineParts<Eigen::Vector4d>(*this, j, path, "quaternions", "an array of [w, x, y, z] quaternions",
                                                  [&](const json& e, const std::string& ep) { return quaternion(e, ep); });
  if (!parts) return std::nullopt;
  QuaternionSpline spline(parts->degree, parts->knots, parts->controls);
  if (!domainMatches(*this, spline.domainBegin(), spline.domainEnd(), curve, memberPath(path, "knots"))) return std::nullopt;
  return spline;
}

std::optional<double> DesignReader::youngsModulus(const json& j, const std::string& path) {
  auto v = positive(j, path, "a Young's modulus in MPa");
  if (v && *v > kMaxModulusMpa) {
    fail(path, "expected a Young's modulus of at most " + describe(json(kMaxModulusMpa)) +
                   " MPa (stiffer than any printable material), got " + describe(j));
    return std::nullopt;
  }
  if (v && *v < kMinModulusMpa) {
    fail(path, "expected a Young's modulus of at least " + describe(json(kMinModulusMpa)) +
                   " MPa (1 Pa: softer than any solid that keeps a shape), got " + describe(j));
    return std::nullopt;
  }
  return v;
}

std::optional<BSplineField> DesignReader::modulus(const json& j, const std::string& path, const NurbsCurve* curve) {
  if (j.is_number()) {
    auto v = youngsModulus(j, path);
    if (!v || !curve) return std::nullopt;
    return BSplineField::constant(*v, curve->domainBegin(), curve->domainEnd());
  }
  if (!j.is_object()) {
    fail(path, "expected a modulus in MPa (a number > 0) or a B-spline {degree, knots, values}, got " + describe(j));
    return std::nullopt;
  }
  onlyKeys(j, path, {"degree", "knots", "values"});
  const auto parts = splineParts<double>(*this, j, path, "values", "an array of moduli in MPa",
                                         [&](const json& e, const std::string& ep) { return youngsModulus(e, ep); });
  if (!parts) return std::nullopt;
  BSplineField field(parts->degree, parts->knots, parts->controls);
  if (!domainMatches(*this, field.domainBegin(), field.domainEnd(), curve, memberPath(path, "knots"))) return std::nullopt;
  return curve ? std::optional<BSplineField>(field) : std::nullopt;
}

std::optional<RodParts> DesignReader::rod(const json& j, const std::string& path, RodNames& names) {
  if (!j.is_object()) {
    fail(path, "expected a rod object, got " + describe(j));
    return std::nullopt;
  }
  onlyKeys(j, path, {"name", "centerline", "section", "normal", "orientation", "caps", "modulus"});
  const std::size_t before = issues.size();

  std::string name;
  if (auto n = require(j, path, "name", "a rod name")) {
    if (auto s = this->name(*n, memberPath(path, "name"), "a rod name")) {
      name = *s;
      auto [it, fresh] = names.emplace(name, path);
      if (!fresh) fail(memberPath(path, "name"), "duplicate rod name \"" + name + "\" (also " + it->second + ")");
    }
  }
  std::optional<NurbsCurve> curve;
  if (auto c = require(j, path, "centerline", "a NURBS curve {degree, knots, points, weights}"))
    curve = centerline(*c, memberPath(path, "centerline"), CenterlineLength::LeftToRod);
  std::optional<Section> sec;
  if (auto s = require(j, path, "section", "a cross-section {shape, ...}")) sec = section(*s, memberPath(path, "section"));

  std::optional<Vec3> normal;
  std::optional<QuaternionSpline> orient;
  const auto nIt = j.find("normal");
  const auto oIt = j.find("orientation");
  if (nIt != j.end() && oIt != j.end()) fail(path, "give either \"normal\" or \"orientation\", not both");
  if (nIt != j.end()) normal = referenceNormal(*nIt, memberPath(path, "normal"), curve ? &*curve : nullptr);
  if (oIt != j.end()) orient = orientation(*oIt, memberPath(path, "orientation"), curve ? &*curve : nullptr);
  if (sec && !sec->isRotationallySymmetric() && nIt == j.end() && oIt == j.end())
    fail(path, "a " + std::string(toString(sec->shape)) + " section needs a frame: give \"normal\" or \"orientation\"");

  CapStyle caps = CapStyle::Round;
  if (auto c = j.find("caps"); c != j.end()) {
    if (*c == "round") caps = CapStyle::Round;
    else if (*c == "flat") caps = CapStyle::Flat;
    else fail(memberPath(path, "caps"), "expected \"round\" or \"flat\", got " + describe(*c));
  }
  std::optional<BSplineField> e;
  if (auto m = require(j, path, "modulus", "a Young's modulus in MPa or a B-spline {degree, knots, values}"))
    e = modulus(*m, memberPath(path, "modulus"), curve ? &*curve : nullptr);

  if (issues.size() != before || !curve || !sec || !e) return std::nullopt;
  return RodParts{name, std::move(*curve), *sec, normal, std::move(orient), caps, std::move(*e)};
}

}  // namespace rodfab::geometry
