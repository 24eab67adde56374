// Reading design files: strict JSON, then every check of the format, units and rods, each violation
// recorded at its JSON path (geometry/design_reader.hpp). The blocks of higher stages are read there.
#include "geometry/design_reader.hpp"

#include "common/json_input.hpp"
#include "common/located_issues.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string_view>

namespace rodfab::geometry {

using nlohmann::json;

namespace {

// Number literals too large for a double (1e999) stop nlohmann's parser with no path. Before parsing,
// each is replaced by a string with this prefix, so the validator names its JSON path and the
// file's other errors are still found.
constexpr std::string_view kOverflowTag = "\x01rodfab-overflow:";

std::optional<std::string> overflowLiteral(const json& j) {
  if (!j.is_string()) return std::nullopt;
  const std::string& s = j.get_ref<const std::string&>();
  if (!s.starts_with(kOverflowTag)) return std::nullopt;
  return s.substr(kOverflowTag.size());
}

// `text` with every number literal outside strings that overflows a double replaced as above.
std::string tagOverflowingNumbers(const std::string& text) {
  std::string out;
  std::size_t copied = 0;
  for (std::size_t at = 0; at < text.size();) {
    const char c = text[at];
    if (c == '"') {  // skip the string, escapes included
      for (++at; at < text.size() && text[at] != '"'; ++at)
        if (text[at] == '\\') ++at;
      ++at;
      continue;
    }
    if (c != '-' && !(c >= '0' && c <= '9')) {
      ++at;
      continue;
    }
    std::size_t end = at + 1;
    while (end < text.size() && std::strchr("0123456789.eE+-", text[end])) ++end;
    const std::string literal = text.substr(at, end - at);
    char* parsedEnd = nullptr;
    const double v = std::strtod(literal.c_str(), &parsedEnd);
    if (parsedEnd == literal.c_str() + literal.size() && !std::isfinite(v)) {
      out.append(text, copied, at - copied);
      out += json(std::string(kOverflowTag) + literal).dump();
      copied = end;
    }
    at = end;
  }
  if (copied == 0) return text;
  out.append(text, copied, std::string::npos);
  return out;
}

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

}  // namespace

std::string describe(const json& j) {
  if (const auto literal = overflowLiteral(j)) return *literal + " (beyond the range of a double)";
  std::string s = j.dump();
  if (s.size() > 40) s = s.substr(0, 37) + "...";
  return s;
}

std::string indexPath(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }
std::string memberPath(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }

void DesignReader::fail(const std::string& path, const std::string& message) { issues.push_back({path, message}); }

void DesignReader::onlyKeys(const json& obj, const std::string& path, const std::set<std::string>& allowed) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    if (allowed.count(it.key())) continue;
    std::string list;
    for (const auto& k : allowed) list += (list.empty() ? "" : ", ") + k;
    fail(memberPath(path, it.key()), "unknown key (expected one of: " + list + ")");
  }
}

const json* DesignReader::require(const json& obj, const std::string& path, const std::string& key, const std::string& what) {
  auto it = obj.find(key);
  if (it == obj.end()) {
    fail(memberPath(path, key), "missing; expected " + what);
    return nullptr;
  }
  return &*it;
}

std::optional<double> DesignReader::number(const json& j, const std::string& path, const std::string& what) {
  if (overflowLiteral(j)) {
    fail(path, "expected a finite number, got " + describe(j));
    return std::nullopt;
  }
  if (!j.is_number()) {
    fail(path, "expected " + what + ", got " + describe(j));
    return std::nullopt;
  }
  const double v = j.get<double>();
  if (!std::isfinite(v)) {
    fail(path, "expected a finite number, got " + describe(j));
    return std::nullopt;
  }
  return v;
}

std::optional<double> DesignReader::positive(const json& j, const std::string& path, const std::string& what) {
  auto v = number(j, path, what + " (a number > 0)");
  if (v && !(*v > 0.0)) {
    fail(path, "expected " + what + " > 0, got " + describe(j));
    return std::nullopt;
  }
  return v;
}

std::optional<int> DesignReader::degree(const json& j, const std::string& path) {
  if (!j.is_number_integer() || j.get<long long>() < 1 || j.get<long long>() > kMaxDegree) {
    fail(path, "expected an integer degree from 1 to " + std::to_string(kMaxDegree) + ", got " + describe(j));
    return std::nullopt;
  }
  return j.get<int>();
}

std::optional<Vec3> DesignReader::vector3(const json& j, const std::string& path, const std::string& what) {
  if (!j.is_array() || j.size() != 3) {
    fail(path, "expected " + what + " as [x, y, z], got " + describe(j));
    return std::nullopt;
  }
  Vec3 v;
  bool ok = true;
  for (std::size_t k = 0; k < 3; ++k) {
    auto c = number(j[k], indexPath(path, k), "a number");
    if (c) v[k] = *c; else ok = false;
  }
  return ok ? std::optional<Vec3>(v) : std::nullopt;
}

std::optional<std::vector<double>> DesignReader::knots(const json& j, const std::string& path, std::optional<int> p,
                                                     std::optional<std::size_t> count) {
  if (!j.is_array()) {
    fail(path, "expected an array of knot values, got " + describe(j));
    return std::nullopt;
  }
  std::vector<double> k;
  bool ok = true;
  for (std::size_t i = 0; i < j.size(); ++i) {
    auto v = number(j[i], indexPath(path, i), "a knot value (number)");
    if (!v) { ok = false; continue; }
    if (!k.empty() && *v < k.back())
      fail(indexPath(path, i), "knots must be non-decreasing: " + describe(j[i]) + " follows " + describe(j[i - 1])), ok = false;
    k.push_back(*v);
  }
  if (!ok) return std::nullopt;
  if (p && count) {
    const std::size_t expected = *count + *p + 1;
    if (k.size() != expected) {
      fail(path, "expected " + std::to_string(expected) + " knots (" + std::to_string(*count) +
                     " control values + degree " + std::to_string(*p) + " + 1), got " + std::to_string(k.size()));
      return std::nullopt;
    }
    if (!(k[*count] > k[*p])) {
      fail(path, "empty parameter domain: knots[" + std::to_string(*p) + "] and knots[" + std::to_string(*count) +
                     "] must differ");
      return std::nullopt;
    }
    // An interior knot repeated more than `degree` times splits the curve in two.
    for (std::size_t i = *p + 1; i < *count;) {
      std::size_t m = 1;
      while (i + m < *count && k[i + m] == k[i]) ++m;
      if (m > static_cast<std::size_t>(*p)) {
        fail(indexPath(path, i), "interior knot " + describe(j[i]) + " repeated " + std::to_string(m) +
                                 " times; at most the degree (" + std::to_string(*p) + ") keeps the curve connected");
        return std::nullopt;
      }
      i += m;
    }
  }
  return k;
}

std::optional<std::string> DesignReader::string(const json& j, const std::string& path, const std::string& what) {
  if (!j.is_string()) {
    fail(path, "expected " + what + " (a string), got " + describe(j));
    return std::nullopt;
  }
  return j.get<std::string>();
}

std::optional<NurbsCurve> DesignReader::centerline(const json& j, const std::string& path) {
  if (!j.is_object()) {
    fail(path, "expected an object {degree, knots, points, weights}, got " + describe(j));
    return std::nullopt;
  }
  onlyKeys(j, path, {"degree", "knots", "points", "weights"});
  std::optional<int> p;
  if (auto d = require(j, path, "degree", "an integer degree")) p = degree(*d, memberPath(path, "degree"));
  std::optional<std::vector<Vec3>> points;
  if (auto pts = require(j, path, "points", "an array of [x, y, z] control points")) {
    const std::string pp = memberPath(path, "points");
    if (!pts->is_array()) {
      fail(pp, "expected an array of [x, y, z] control points, got " + describe(*pts));
    } else {
      std::vector<Vec3> v;
      bool ok = true;
      for (std::size_t i = 0; i < pts->size(); ++i) {
        auto c = vector3((*pts)[i], indexPath(pp, i), "a control point");
        if (c && !(c->cwiseAbs().maxCoeff() <= kMaxCoordinateMm)) {
          fail(indexPath(pp, i), "expected coordinates within +-1e9 mm (designs are in millimetres), got " + describe((*pts)[i]));
          c.reset();
        }
        if (c) v.push_back(*c); else ok = false;
      }
      if (ok && p && v.size() < static_cast<std::size_t>(*p) + 1) {
        fail(pp, "a degree-" + std::to_string(*p) + " curve needs at least " + std::to_string(*p + 1) +
                     " control points, got " + std::to_string(v.size()));
        ok = false;
      }
      if (ok) points = std::move(v);
    }
  }
  const std::optional<std::vector<double>> k =
      splineKnots(*this, j, path, p, points ? std::optional<std::size_t>(points->size()) : std::nullopt);
  std::vector<double> weights;
  bool weightsOk = true;
  if (auto w = j.find("weights"); w != j.end()) {
    const std::string wp = memberPath(path, "weights");
    if (!w->is_array()) {
      fail(wp, "expected an array of positive weights, got " + describe(*w));
      weightsOk = false;
    } else {
      for (std::size_t i = 0; i < w->size(); ++i) {
        auto v = positive((*w)[i], indexPath(wp, i), "a weight");
        if (v) weights.push_back(*v); else weightsOk = false;
      }
      if (weightsOk && points && weights.size() != points->size()) {
        fail(wp, "expected one weight per control point (" + std::to_string(points->size()) + "), got " +
                     std::to_string(weights.size()));
        weightsOk = false;
      }
    }
  }
  if (!p || !points || !k || !weightsOk) return std::nullopt;
  NurbsCurve curve(*p, *k, *points, weights);
  const double length = curve.arcLength();
  Box3 box;
  for (const Vec3& q : *points) box.extend(q);
  if (!std::isfinite(length)) {
    fail(path, "the centerline's length is not a finite number (weights too extreme for double precision?)");
    return std::nullopt;
  }
  if (!(length > 1e-9 * std::max(1.0, box.diagonal().norm()))) {
    fail(path, "degenerate centerline: its length is zero (all control points coincide?)");
    return std::nullopt;
  }
  return curve;
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
    auto v = positive(*d, memberPath(path, "diameter"), "a diameter in mm");
    return v ? std::optional<Section>(Section::circle(*v)) : std::nullopt;
  }
  if (*name == "ellipse" || *name == "rectangle") {
    onlyKeys(j, path, {"shape", "width", "height"});
    std::optional<double> w, h;
    if (auto x = require(j, path, "width", "the width along d1 in mm")) w = positive(*x, memberPath(path, "width"), "a width in mm");
    if (auto x = require(j, path, "height", "the height along d2 in mm")) h = positive(*x, memberPath(path, "height"), "a height in mm");
    if (!w || !h) return std::nullopt;
    return *name == "ellipse" ? Section::ellipse(*w, *h) : Section::rectangle(*w, *h);
  }
  fail(memberPath(path, "shape"), "unknown section shape " + describe(*shape) + " (expected \"circle\", \"ellipse\" or \"rectangle\")");
  return std::nullopt;
}

std::optional<QuaternionSpline> DesignReader::orientation(const json& j, const std::string& path, const NurbsCurve* curve) {
  if (!j.is_object()) {
    fail(path, "expected an object {degree, knots, quaternions}, got " + describe(j));
    return std::nullopt;
  }
  onlyKeys(j, path, {"degree", "knots", "quaternions"});
  std::optional<int> p;
  if (auto d = require(j, path, "degree", "an integer degree")) p = degree(*d, memberPath(path, "degree"));
  std::optional<std::vector<Eigen::Vector4d>> quats;
  if (auto q = require(j, path, "quaternions", "an array of [w, x, y, z] quaternions")) {
    const std::string qp = memberPath(path, "quaternions");
    if (!q->is_array()) {
      fail(qp, "expected an array of [w, x, y, z] quaternions, got " + describe(*q));
    } else {
      std::vector<Eigen::Vector4d> v;
      bool ok = true;
      for (std::size_t i = 0; i < q->size(); ++i) {
        const json& e = (*q)[i];
        if (!e.is_array() || e.size() != 4) {
          fail(indexPath(qp, i), "expected a quaternion [w, x, y, z], got " + describe(e));
          ok = false;
          continue;
        }
        Eigen::Vector4d c;
        bool cok = true;
        for (std::size_t k = 0; k < 4; ++k) {
          auto x = number(e[k], indexPath(indexPath(qp, i), k), "a number");
          if (x) c[k] = *x; else cok = false;
        }
        if (cok && !(c.cwiseAbs().maxCoeff() > 0.0)) {  // not c.norm(): 1e-170 would underflow to zero
          fail(indexPath(qp, i), "a zero quaternion has no rotation");
          cok = false;
        }
        if (cok) v.push_back(c); else ok = false;
      }
      if (ok && !enoughControls(*this, p, v.size(), qp, "quaternions")) ok = false;
      if (ok) quats = std::move(v);
    }
  }
  const std::optional<std::vector<double>> k =
      splineKnots(*this, j, path, p, quats ? std::optional<std::size_t>(quats->size()) : std::nullopt);
  if (!p || !quats || !k) return std::nullopt;
  QuaternionSpline spline(*p, *k, *quats);
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
  std::optional<int> p;
  if (auto d = require(j, path, "degree", "an integer degree")) p = degree(*d, memberPath(path, "degree"));
  std::optional<std::vector<double>> values;
  if (auto v = require(j, path, "values", "an array of moduli in MPa")) {
    const std::string vp = memberPath(path, "values");
    if (!v->is_array()) {
      fail(vp, "expected an array of moduli in MPa, got " + describe(*v));
    } else {
      std::vector<double> out;
      bool ok = true;
      for (std::size_t i = 0; i < v->size(); ++i) {
        auto x = youngsModulus((*v)[i], indexPath(vp, i));
        if (x) out.push_back(*x); else ok = false;
      }
      if (ok && !enoughControls(*this, p, out.size(), vp, "values")) ok = false;
      if (ok) values = std::move(out);
    }
  }
  const std::optional<std::vector<double>> k =
      splineKnots(*this, j, path, p, values ? std::optional<std::size_t>(values->size()) : std::nullopt);
  if (!p || !values || !k) return std::nullopt;
  BSplineField field(*p, *k, *values);
  if (!domainMatches(*this, field.domainBegin(), field.domainEnd(), curve, memberPath(path, "knots"))) return std::nullopt;
  return curve ? std::optional<BSplineField>(field) : std::nullopt;
}

std::optional<Rod> DesignReader::rod(const json& j, const std::string& path, RodNames& names) {
  if (!j.is_object()) {
    fail(path, "expected a rod object, got " + describe(j));
    return std::nullopt;
  }
  onlyKeys(j, path, {"name", "centerline", "section", "normal", "orientation", "caps", "modulus"});
  const std::size_t before = issues.size();

  std::string name;
  if (auto n = require(j, path, "name", "a rod name")) {
    if (auto s = string(*n, memberPath(path, "name"), "a rod name")) {
      name = *s;
      if (name.empty()) fail(memberPath(path, "name"), "expected a non-empty rod name");
      auto [it, fresh] = names.emplace(name, path);
      if (!fresh) fail(memberPath(path, "name"), "duplicate rod name \"" + name + "\" (also " + it->second + ")");
    }
  }
  std::optional<NurbsCurve> curve;
  if (auto c = require(j, path, "centerline", "a NURBS curve {degree, knots, points, weights}"))
    curve = centerline(*c, memberPath(path, "centerline"));
  std::optional<Section> sec;
  if (auto s = require(j, path, "section", "a cross-section {shape, ...}")) sec = section(*s, memberPath(path, "section"));

  std::optional<Vec3> normal;
  std::optional<QuaternionSpline> orient;
  const auto nIt = j.find("normal");
  const auto oIt = j.find("orientation");
  if (nIt != j.end() && oIt != j.end()) fail(path, "give either \"normal\" or \"orientation\", not both");
  if (nIt != j.end()) {
    const std::string np = memberPath(path, "normal");
    normal = vector3(*nIt, np, "a reference normal");
    if (normal && !(normal->cwiseAbs().maxCoeff() > 0.0)) {
      fail(np, "the reference normal must not be zero");
      normal.reset();
    } else if (normal && curve) {
      Vec3 d[3];
      curve->derivatives(curve->domainBegin(), 2, d);
      const Vec3 t = unitTangent(d[1], d[2]);
      if ((*normal * powerOfTwoScale(*normal)).normalized().cross(t).norm() < 1e-6) {  // scaled: 1e300 does not overflow
        fail(np, "the reference normal " + describe(*nIt) + " is parallel to the centerline's tangent at its start; "
                 "expected a direction across the rod");
        normal.reset();
      }
    }
  }
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
  try {
    return Rod(name, *curve, *sec, normal, orient, caps, *e);
  } catch (const std::invalid_argument& error) {  // e.g. a centerline too intricate to sample
    fail(path, error.what());
    return std::nullopt;
  }
}

DesignError::DesignError(std::string file, std::vector<DesignIssue> issues)
    : IssueListError(common::formatLocatedIssues(file, issues), file, issues) {}

namespace {

// The document of `text`; throws DesignError when it is not JSON.
json parseDocument(const std::string& text, const std::string& sourceName) {
  try {
    return common::parseJsonStrict(tagOverflowingNumbers(text));
  } catch (const common::JsonInputError& e) {
    throw DesignError(sourceName, {{e.path, e.message}});
  } catch (const json::out_of_range& e) {
    // A number too large for a double (1e999) that the tagging missed: locate the literal it names.
    std::string what = e.what();
    std::string where;
    const auto q0 = what.find('\''), q1 = what.rfind('\'');
    if (q0 != std::string::npos && q1 > q0) {
      if (auto at = text.find(what.substr(q0 + 1, q1 - q0 - 1)); at != std::string::npos) {
        const auto [line, column] = common::lineAndColumn(text, at);
        where = " at line " + std::to_string(line) + ", column " + std::to_string(column);
      }
    }
    if (auto pos = what.find("number overflow"); pos != std::string::npos) what = what.substr(pos);
    throw DesignError(sourceName, {{"", "expected finite numbers" + where + ": " + what}});
  }
}

}  // namespace

DesignDocument parseDesignDocument(const std::string& text, const std::string& sourceName, DesignReader& v) {
  DesignDocument d;
  d.json = parseDocument(text, sourceName);
  d.structure.source = sourceName;
  const json& doc = d.json;
  if (!doc.is_object()) throw DesignError(sourceName, {{"", "expected a JSON object with \"format\" and \"rods\""}});
  v.onlyKeys(doc, "", {"format", "units", "rods", "description", "metadata", "mechanics", "optimize"});
  if (auto f = v.require(doc, "", "format", std::string("\"") + kDesignFormat + "\"")) {
    if (!f->is_string() || *f != kDesignFormat)
      v.fail("format", "unsupported format " + describe(*f) + " (this rodfab reads \"" + kDesignFormat + "\")");
  }
  if (auto u = doc.find("units"); u != doc.end() && *u != "mm")
    v.fail("units", "expected \"mm\" (designs are in millimetres), got " + describe(*u));
  if (auto desc = doc.find("description"); desc != doc.end() && !desc->is_string())
    v.fail("description", "expected a string, got " + describe(*desc));
  if (auto rods = v.require(doc, "", "rods", "a non-empty array of rods")) {
    if (!rods->is_array() || rods->empty()) {
      v.fail("rods", "expected a non-empty array of rods, got " + describe(*rods));
    } else {
      d.rodsListed = true;
      for (std::size_t i = 0; i < rods->size(); ++i)
        if (auto r = v.rod((*rods)[i], indexPath("rods", i), d.rodNames)) d.structure.rods.push_back(std::move(*r));
    }
  }
  return d;
}

RodStructure parseDesign(const std::string& text, const std::string& sourceName) {
  DesignReader reader;
  DesignDocument d = parseDesignDocument(text, sourceName, reader);
  if (!reader.issues.empty()) throw DesignError(sourceName, std::move(reader.issues));
  return std::move(d.structure);
}

std::string readDesignText(const std::filesystem::path& file) {
  try {
    return common::readBoundedFile(file.string());
  } catch (const common::JsonInputError& e) {
    throw DesignError(file.string(), {{"", e.message}});
  }
}

RodStructure readDesign(const std::filesystem::path& file) { return parseDesign(readDesignText(file), file.string()); }

}  // namespace rodfab::geometry
