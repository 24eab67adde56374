#include "geometry/design_file.hpp"

#include "common/json_input.hpp"
#include "common/output_file.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>

namespace rodfab::geometry {

using nlohmann::json;

namespace {

std::string formatIssues(const std::string& file, const std::vector<DesignIssue>& issues) {
  std::ostringstream out;
  for (std::size_t i = 0; i < issues.size(); ++i) {
    if (i) out << '\n';
    out << file << ": ";
    if (!issues[i].path.empty()) out << issues[i].path << ": ";
    out << issues[i].message;
  }
  return out.str();
}

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

std::string describe(const json& j) {
  if (const auto literal = overflowLiteral(j)) return *literal + " (beyond the range of a double)";
  std::string s = j.dump();
  if (s.size() > 40) s = s.substr(0, 37) + "...";
  return s;
}

std::string index(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }
std::string member(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }

// Collects every violation of one file; each check returns what it could read so later checks can go on.
class Validator {
public:
  std::vector<DesignIssue> issues;

  void fail(const std::string& path, const std::string& message) { issues.push_back({path, message}); }

  void onlyKeys(const json& obj, const std::string& path, const std::set<std::string>& allowed) {
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      if (allowed.count(it.key())) continue;
      std::string list;
      for (const auto& k : allowed) list += (list.empty() ? "" : ", ") + k;
      fail(member(path, it.key()), "unknown key (expected one of: " + list + ")");
    }
  }

  const json* require(const json& obj, const std::string& path, const std::string& key, const std::string& what) {
    auto it = obj.find(key);
    if (it == obj.end()) {
      fail(member(path, key), "missing; expected " + what);
      return nullptr;
    }
    return &*it;
  }

  std::optional<double> number(const json& j, const std::string& path, const std::string& what) {
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

  std::optional<double> positive(const json& j, const std::string& path, const std::string& what) {
    auto v = number(j, path, what + " (a number > 0)");
    if (v && !(*v > 0.0)) {
      fail(path, "expected " + what + " > 0, got " + describe(j));
      return std::nullopt;
    }
    return v;
  }

  std::optional<int> degree(const json& j, const std::string& path) {
    if (!j.is_number_integer() || j.get<long long>() < 1 || j.get<long long>() > kMaxDegree) {
      fail(path, "expected an integer degree from 1 to " + std::to_string(kMaxDegree) + ", got " + describe(j));
      return std::nullopt;
    }
    return j.get<int>();
  }

  std::optional<Vec3> vector3(const json& j, const std::string& path, const std::string& what) {
    if (!j.is_array() || j.size() != 3) {
      fail(path, "expected " + what + " as [x, y, z], got " + describe(j));
      return std::nullopt;
    }
    Vec3 v;
    bool ok = true;
    for (std::size_t k = 0; k < 3; ++k) {
      auto c = number(j[k], index(path, k), "a number");
      if (c) v[k] = *c; else ok = false;
    }
    return ok ? std::optional<Vec3>(v) : std::nullopt;
  }

  // A knot vector for `count` control values of degree `p` (either may be unknown: then only the
  // entries are checked).
  std::optional<std::vector<double>> knots(const json& j, const std::string& path, std::optional<int> p,
                                           std::optional<std::size_t> count) {
    if (!j.is_array()) {
      fail(path, "expected an array of knot values, got " + describe(j));
      return std::nullopt;
    }
    std::vector<double> k;
    bool ok = true;
    for (std::size_t i = 0; i < j.size(); ++i) {
      auto v = number(j[i], index(path, i), "a knot value (number)");
      if (!v) { ok = false; continue; }
      if (!k.empty() && *v < k.back())
        fail(index(path, i), "knots must be non-decreasing: " + describe(j[i]) + " follows " + describe(j[i - 1])), ok = false;
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
          fail(index(path, i), "interior knot " + describe(j[i]) + " repeated " + std::to_string(m) +
                                   " times; at most the degree (" + std::to_string(*p) + ") keeps the curve connected");
          return std::nullopt;
        }
        i += m;
      }
    }
    return k;
  }

  std::optional<std::string> string(const json& j, const std::string& path, const std::string& what) {
    if (!j.is_string()) {
      fail(path, "expected " + what + " (a string), got " + describe(j));
      return std::nullopt;
    }
    return j.get<std::string>();
  }

  bool sameDomain(double a0, double a1, double b0, double b1) {
    const double tol = 1e-9 * std::max({1.0, std::abs(a0), std::abs(a1)});
    return std::abs(a0 - b0) <= tol && std::abs(a1 - b1) <= tol;
  }

  std::optional<NurbsCurve> centerline(const json& j, const std::string& path) {
    if (!j.is_object()) {
      fail(path, "expected an object {degree, knots, points, weights}, got " + describe(j));
      return std::nullopt;
    }
    onlyKeys(j, path, {"degree", "knots", "points", "weights"});
    std::optional<int> p;
    if (auto d = require(j, path, "degree", "an integer degree")) p = degree(*d, member(path, "degree"));
    std::optional<std::vector<Vec3>> points;
    if (auto pts = require(j, path, "points", "an array of [x, y, z] control points")) {
      const std::string pp = member(path, "points");
      if (!pts->is_array()) {
        fail(pp, "expected an array of [x, y, z] control points, got " + describe(*pts));
      } else {
        std::vector<Vec3> v;
        bool ok = true;
        for (std::size_t i = 0; i < pts->size(); ++i) {
          auto c = vector3((*pts)[i], index(pp, i), "a control point");
          if (c && !(c->cwiseAbs().maxCoeff() <= kMaxCoordinateMm)) {
            fail(index(pp, i), "expected coordinates within +-1e9 mm (designs are in millimetres), got " + describe((*pts)[i]));
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
    std::optional<std::vector<double>> k;
    if (auto kn = require(j, path, "knots", "an array of knot values"))
      k = knots(*kn, member(path, "knots"), p, points ? std::optional<std::size_t>(points->size()) : std::nullopt);
    std::vector<double> weights;
    bool weightsOk = true;
    if (auto w = j.find("weights"); w != j.end()) {
      const std::string wp = member(path, "weights");
      if (!w->is_array()) {
        fail(wp, "expected an array of positive weights, got " + describe(*w));
        weightsOk = false;
      } else {
        for (std::size_t i = 0; i < w->size(); ++i) {
          auto v = positive((*w)[i], index(wp, i), "a weight");
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

  std::optional<Section> section(const json& j, const std::string& path) {
    if (!j.is_object()) {
      fail(path, "expected an object {shape, ...}, got " + describe(j));
      return std::nullopt;
    }
    const json* shape = require(j, path, "shape", "\"circle\", \"ellipse\" or \"rectangle\"");
    if (!shape) return std::nullopt;
    auto name = string(*shape, member(path, "shape"), "the section shape");
    if (!name) return std::nullopt;
    if (*name == "circle") {
      onlyKeys(j, path, {"shape", "diameter"});
      const json* d = require(j, path, "diameter", "the diameter in mm");
      if (!d) return std::nullopt;
      auto v = positive(*d, member(path, "diameter"), "a diameter in mm");
      return v ? std::optional<Section>(Section::circle(*v)) : std::nullopt;
    }
    if (*name == "ellipse" || *name == "rectangle") {
      onlyKeys(j, path, {"shape", "width", "height"});
      std::optional<double> w, h;
      if (auto x = require(j, path, "width", "the width along d1 in mm")) w = positive(*x, member(path, "width"), "a width in mm");
      if (auto x = require(j, path, "height", "the height along d2 in mm")) h = positive(*x, member(path, "height"), "a height in mm");
      if (!w || !h) return std::nullopt;
      return *name == "ellipse" ? Section::ellipse(*w, *h) : Section::rectangle(*w, *h);
    }
    fail(member(path, "shape"), "unknown section shape " + describe(*shape) + " (expected \"circle\", \"ellipse\" or \"rectangle\")");
    return std::nullopt;
  }

  std::optional<QuaternionSpline> orientation(const json& j, const std::string& path, const NurbsCurve* curve) {
    if (!j.is_object()) {
      fail(path, "expected an object {degree, knots, quaternions}, got " + describe(j));
      return std::nullopt;
    }
    onlyKeys(j, path, {"degree", "knots", "quaternions"});
    std::optional<int> p;
    if (auto d = require(j, path, "degree", "an integer degree")) p = degree(*d, member(path, "degree"));
    std::optional<std::vector<Eigen::Vector4d>> quats;
    if (auto q = require(j, path, "quaternions", "an array of [w, x, y, z] quaternions")) {
      const std::string qp = member(path, "quaternions");
      if (!q->is_array()) {
        fail(qp, "expected an array of [w, x, y, z] quaternions, got " + describe(*q));
      } else {
        std::vector<Eigen::Vector4d> v;
        bool ok = true;
        for (std::size_t i = 0; i < q->size(); ++i) {
          const json& e = (*q)[i];
          if (!e.is_array() || e.size() != 4) {
            fail(index(qp, i), "expected a quaternion [w, x, y, z], got " + describe(e));
            ok = false;
            continue;
          }
          Eigen::Vector4d c;
          bool cok = true;
          for (std::size_t k = 0; k < 4; ++k) {
            auto x = number(e[k], index(index(qp, i), k), "a number");
            if (x) c[k] = *x; else cok = false;
          }
          if (cok && !(c.cwiseAbs().maxCoeff() > 0.0)) {  // not c.norm(): 1e-170 would underflow to zero
            fail(index(qp, i), "a zero quaternion has no rotation");
            cok = false;
          }
          if (cok) v.push_back(c); else ok = false;
        }
        if (ok && p && v.size() < static_cast<std::size_t>(*p) + 1) {
          fail(qp, "degree " + std::to_string(*p) + " needs at least " + std::to_string(*p + 1) + " quaternions, got " +
                       std::to_string(v.size()));
          ok = false;
        }
        if (ok) quats = std::move(v);
      }
    }
    std::optional<std::vector<double>> k;
    if (auto kn = require(j, path, "knots", "an array of knot values"))
      k = knots(*kn, member(path, "knots"), p, quats ? std::optional<std::size_t>(quats->size()) : std::nullopt);
    if (!p || !quats || !k) return std::nullopt;
    QuaternionSpline spline(*p, *k, *quats);
    if (curve && !sameDomain(spline.domainBegin(), spline.domainEnd(), curve->domainBegin(), curve->domainEnd())) {
      fail(member(path, "knots"), "parameter domain [" + std::to_string(spline.domainBegin()) + ", " +
                                      std::to_string(spline.domainEnd()) + "] must equal the centerline's [" +
                                      std::to_string(curve->domainBegin()) + ", " + std::to_string(curve->domainEnd()) + "]");
      return std::nullopt;
    }
    return spline;
  }

  // A Young's modulus in MPa: > 0 and at most kMaxModulusMpa (grids store moduli as floats).
  std::optional<double> youngsModulus(const json& j, const std::string& path) {
    auto v = positive(j, path, "a Young's modulus in MPa");
    if (v && *v > kMaxModulusMpa) {
      fail(path, "expected a Young's modulus of at most " + describe(json(kMaxModulusMpa)) +
                     " MPa (stiffer than any printable material), got " + describe(j));
      return std::nullopt;
    }
    return v;
  }

  std::optional<BSplineField> modulus(const json& j, const std::string& path, const NurbsCurve* curve) {
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
    if (auto d = require(j, path, "degree", "an integer degree")) p = degree(*d, member(path, "degree"));
    std::optional<std::vector<double>> values;
    if (auto v = require(j, path, "values", "an array of moduli in MPa")) {
      const std::string vp = member(path, "values");
      if (!v->is_array()) {
        fail(vp, "expected an array of moduli in MPa, got " + describe(*v));
      } else {
        std::vector<double> out;
        bool ok = true;
        for (std::size_t i = 0; i < v->size(); ++i) {
          auto x = youngsModulus((*v)[i], index(vp, i));
          if (x) out.push_back(*x); else ok = false;
        }
        if (ok && p && out.size() < static_cast<std::size_t>(*p) + 1) {
          fail(vp, "degree " + std::to_string(*p) + " needs at least " + std::to_string(*p + 1) + " values, got " +
                       std::to_string(out.size()));
          ok = false;
        }
        if (ok) values = std::move(out);
      }
    }
    std::optional<std::vector<double>> k;
    if (auto kn = require(j, path, "knots", "an array of knot values"))
      k = knots(*kn, member(path, "knots"), p, values ? std::optional<std::size_t>(values->size()) : std::nullopt);
    if (!p || !values || !k) return std::nullopt;
    BSplineField field(*p, *k, *values);
    if (curve && !sameDomain(field.domainBegin(), field.domainEnd(), curve->domainBegin(), curve->domainEnd())) {
      fail(member(path, "knots"), "parameter domain [" + std::to_string(field.domainBegin()) + ", " +
                                      std::to_string(field.domainEnd()) + "] must equal the centerline's [" +
                                      std::to_string(curve->domainBegin()) + ", " + std::to_string(curve->domainEnd()) + "]");
      return std::nullopt;
    }
    return curve ? std::optional<BSplineField>(field) : std::nullopt;
  }

  std::optional<Rod> rod(const json& j, const std::string& path, std::map<std::string, std::string>& names) {
    if (!j.is_object()) {
      fail(path, "expected a rod object, got " + describe(j));
      return std::nullopt;
    }
    onlyKeys(j, path, {"name", "centerline", "section", "normal", "orientation", "caps", "modulus"});
    const std::size_t before = issues.size();

    std::string name;
    if (auto n = require(j, path, "name", "a rod name")) {
      if (auto s = string(*n, member(path, "name"), "a rod name")) {
        name = *s;
        if (name.empty()) fail(member(path, "name"), "expected a non-empty rod name");
        auto [it, fresh] = names.emplace(name, path);
        if (!fresh) fail(member(path, "name"), "duplicate rod name \"" + name + "\" (also " + it->second + ")");
      }
    }
    std::optional<NurbsCurve> curve;
    if (auto c = require(j, path, "centerline", "a NURBS curve {degree, knots, points, weights}"))
      curve = centerline(*c, member(path, "centerline"));
    std::optional<Section> sec;
    if (auto s = require(j, path, "section", "a cross-section {shape, ...}")) sec = section(*s, member(path, "section"));

    std::optional<Vec3> normal;
    std::optional<QuaternionSpline> orient;
    const auto nIt = j.find("normal");
    const auto oIt = j.find("orientation");
    if (nIt != j.end() && oIt != j.end()) fail(path, "give either \"normal\" or \"orientation\", not both");
    if (nIt != j.end()) {
      const std::string np = member(path, "normal");
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
    if (oIt != j.end()) orient = orientation(*oIt, member(path, "orientation"), curve ? &*curve : nullptr);
    if (sec && !sec->isRotationallySymmetric() && nIt == j.end() && oIt == j.end())
      fail(path, "a " + std::string(toString(sec->shape)) + " section needs a frame: give \"normal\" or \"orientation\"");

    CapStyle caps = CapStyle::Round;
    if (auto c = j.find("caps"); c != j.end()) {
      if (*c == "round") caps = CapStyle::Round;
      else if (*c == "flat") caps = CapStyle::Flat;
      else fail(member(path, "caps"), "expected \"round\" or \"flat\", got " + describe(*c));
    }
    std::optional<BSplineField> e;
    if (auto m = require(j, path, "modulus", "a Young's modulus in MPa or a B-spline {degree, knots, values}"))
      e = modulus(*m, member(path, "modulus"), curve ? &*curve : nullptr);

    if (issues.size() != before || !curve || !sec || !e) return std::nullopt;
    try {
      return Rod(name, *curve, *sec, normal, orient, caps, *e);
    } catch (const std::invalid_argument& error) {  // e.g. a centerline too intricate to sample
      fail(path, error.what());
      return std::nullopt;
    }
  }

  // ---- the optional "mechanics" block ----

  // {"rod", "end"}, {"rod", "parameter"} or {"point"}. The parameter's range is checked by the
  // solver, which knows each rod's domain.
  std::optional<RodEndRef> endRef(const json& j, const std::string& path, const std::map<std::string, std::string>& names) {
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
      ref.point = vector3(j["point"], member(path, "point"), "a point in mm");
      for (const char* key : {"end", "parameter"})
        if (j.contains(key)) fail(member(path, key), std::string("\"") + key + "\" goes with \"rod\", not with \"point\"");
      return ref.point ? std::optional<RodEndRef>(ref) : std::nullopt;
    }
    auto name = string(j["rod"], member(path, "rod"), "a rod name");
    if (!name) return std::nullopt;
    if (!names.count(*name)) {
      fail(member(path, "rod"), "no rod is named \"" + *name + "\"");
      return std::nullopt;
    }
    ref.rod = *name;
    if (j.contains("parameter")) {
      if (j.contains("end")) {
        fail(path, "give either \"end\" or \"parameter\", not both");
        return std::nullopt;
      }
      ref.parameter = number(j["parameter"], member(path, "parameter"), "a centerline parameter u");
      return ref.parameter ? std::optional<RodEndRef>(ref) : std::nullopt;
    }
    const json* e = require(j, path, "end", "\"start\" or \"end\" (or \"parameter\": u)");
    if (!e) return std::nullopt;
    if (*e == "start") ref.end = RodEnd::Start;
    else if (*e == "end") ref.end = RodEnd::End;
    else {
      fail(member(path, "end"), "expected \"start\" or \"end\", got " + describe(*e));
      return std::nullopt;
    }
    return ref;
  }

  std::optional<double> ratio(const json& j, const std::string& path, const std::string& what, double lo, double hi) {
    auto v = number(j, path, what);
    if (v && !(*v > lo && *v < hi)) {
      fail(path, "expected " + what + " in (" + describe(lo) + ", " + describe(hi) + "), got " + describe(j));
      return std::nullopt;
    }
    return v;
  }

  template <class Item, class ReadItem>
  void list(const json& obj, const std::string& path, const std::string& key, const std::string& what,
            std::vector<Item>& out, ReadItem readItem) {
    auto it = obj.find(key);
    if (it == obj.end()) return;
    const std::string lp = member(path, key);
    if (!it->is_array()) {
      fail(lp, "expected an array of " + what + ", got " + describe(*it));
      return;
    }
    for (std::size_t i = 0; i < it->size(); ++i) {
      const json& e = (*it)[i];
      const std::string ep = index(lp, i);
      if (!e.is_object()) {
        fail(ep, "expected " + what + " (an object), got " + describe(e));
        continue;
      }
      if (auto item = readItem(e, ep)) out.push_back(std::move(*item));
    }
  }

  MechanicsSpec mechanics(const json& j, const std::string& path, const std::map<std::string, std::string>& names) {
    MechanicsSpec spec;
    spec.present = true;
    if (!j.is_object()) {
      fail(path, "expected an object {poisson_ratio, supports, loads, ...}, got " + describe(j));
      return spec;
    }
    onlyKeys(j, path, {"poisson_ratio", "shear_factor", "joint_tolerance", "joints", "supports", "loads",
                       "distributed_loads", "rods", "load_steps", "load_cases"});
    if (auto v = j.find("poisson_ratio"); v != j.end())
      if (auto x = ratio(*v, member(path, "poisson_ratio"), "a Poisson ratio", -1.0, 0.5)) spec.poissonRatio = *x;
    if (auto v = j.find("shear_factor"); v != j.end())
      spec.shearFactor = positive(*v, member(path, "shear_factor"), "a shear correction factor");
    if (auto v = j.find("joint_tolerance"); v != j.end())
      if (auto x = positive(*v, member(path, "joint_tolerance"), "a distance in mm")) spec.jointTolerance = *x;
    if (auto v = j.find("load_steps"); v != j.end()) {
      if (!v->is_number_integer() || v->get<long long>() < 1 || v->get<long long>() > 100000)
        fail(member(path, "load_steps"), "expected an integer from 1 to 100000, got " + describe(*v));
      else
        spec.loadSteps = v->get<int>();
    }
    if (auto v = j.find("joints"); v != j.end()) {
      const std::string jp = member(path, "joints");
      if (*v == "auto") {
        spec.inferJoints = true;
      } else if (!v->is_array()) {
        fail(jp, "expected \"auto\" (join coincident rod ends) or an array of joints, each an array of rod ends, got " +
                     describe(*v));
      } else {
        spec.inferJoints = false;
        for (std::size_t i = 0; i < v->size(); ++i) {
          const json& joint = (*v)[i];
          const std::string ip = index(jp, i);
          if (!joint.is_array() || joint.size() < 2) {
            fail(ip, "expected an array of at least two rod ends {\"rod\", \"end\"}, got " + describe(joint));
            continue;
          }
          std::vector<RodEndRef> ends;
          for (std::size_t k = 0; k < joint.size(); ++k) {
            auto ref = endRef(joint[k], index(ip, k), names);
            if (ref && ref->point)
              fail(index(ip, k), "joints list rod ends {\"rod\", \"end\"} or rod points {\"rod\", \"parameter\"}, not points");
            else if (ref) ends.push_back(*ref);
          }
          spec.joints.push_back(std::move(ends));
        }
      }
    }
    list(j, path, "supports", "supports {at, type, displacement, rotation}", spec.supports,
         [&](const json& e, const std::string& ep) -> std::optional<Support> {
           onlyKeys(e, ep, {"at", "type", "displacement", "rotation"});
           Support s;
           std::optional<RodEndRef> at;
           if (auto a = require(e, ep, "at", "a place {\"rod\", \"end\"}, {\"rod\", \"parameter\"} or {\"point\"}")) at = endRef(*a, member(ep, "at"), names);
           if (auto t = require(e, ep, "type", "\"clamped\" or \"pinned\"")) {
             if (*t == "clamped") s.kind = SupportKind::Clamped;
             else if (*t == "pinned") s.kind = SupportKind::Pinned;
             else fail(member(ep, "type"), "expected \"clamped\" (position and orientation held) or \"pinned\" (position held), got " + describe(*t));
           }
           if (auto d = e.find("displacement"); d != e.end()) {
             if (auto v = vector3(*d, member(ep, "displacement"), "a displacement in mm")) s.displacement = *v;
           }
           if (auto r = e.find("rotation"); r != e.end()) {
             if (s.kind == SupportKind::Pinned) fail(member(ep, "rotation"), "a pinned support leaves rotation free; use \"type\": \"clamped\" to prescribe it");
             else if (auto v = vector3(*r, member(ep, "rotation"), "a rotation vector (axis times angle, radians)")) s.rotation = *v;
           }
           if (!at) return std::nullopt;
           s.at = *at;
           return s;
         });
    list(j, path, "loads", "point loads {at, force, moment}", spec.loads,
         [&](const json& e, const std::string& ep) -> std::optional<PointLoad> {
           onlyKeys(e, ep, {"at", "force", "moment"});
           PointLoad l;
           std::optional<RodEndRef> at;
           if (auto a = require(e, ep, "at", "a place {\"rod\", \"end\"}, {\"rod\", \"parameter\"} or {\"point\"}")) at = endRef(*a, member(ep, "at"), names);
           bool ok = true;
           if (auto f = e.find("force"); f != e.end()) {
             if (auto v = vector3(*f, member(ep, "force"), "a force in N")) l.force = *v; else ok = false;
           }
           if (auto m = e.find("moment"); m != e.end()) {
             if (auto v = vector3(*m, member(ep, "moment"), "a moment in N mm")) l.moment = *v; else ok = false;
           }
           if (!e.contains("force") && !e.contains("moment")) fail(ep, "a load needs \"force\" (N) or \"moment\" (N mm)"), ok = false;
           if (!at || !ok) return std::nullopt;
           l.at = *at;
           return l;
         });
    list(j, path, "distributed_loads", "distributed loads {rod, force}", spec.distributedLoads,
         [&](const json& e, const std::string& ep) -> std::optional<DistributedLoad> {
           onlyKeys(e, ep, {"rod", "force"});
           DistributedLoad l;
           l.path = ep;
           std::optional<std::string> rod;
           if (auto r = require(e, ep, "rod", "a rod name")) {
             rod = string(*r, member(ep, "rod"), "a rod name");
             if (rod && !names.count(*rod)) fail(member(ep, "rod"), "no rod is named \"" + *rod + "\""), rod.reset();
           }
           std::optional<Vec3> f;
           if (auto x = require(e, ep, "force", "a force per length in N/mm")) f = vector3(*x, member(ep, "force"), "a force per length in N/mm");
           if (!rod || !f) return std::nullopt;
           l.rod = *rod;
           l.force = *f;
           return l;
         });
    if (auto v = j.find("rods"); v != j.end()) {
      const std::string rp = member(path, "rods");
      if (!v->is_object()) {
        fail(rp, "expected an object {ROD NAME: {torsion_constant, shear_factor, poisson_ratio}}, got " + describe(*v));
      } else {
        for (auto it = v->begin(); it != v->end(); ++it) {
          const std::string ep = member(rp, it.key());
          if (!names.count(it.key())) {
            fail(ep, "no rod is named \"" + it.key() + "\"");
            continue;
          }
          if (!it->is_object()) {
            fail(ep, "expected an object {torsion_constant, shear_factor, poisson_ratio}, got " + describe(*it));
            continue;
          }
          onlyKeys(*it, ep, {"torsion_constant", "shear_factor", "poisson_ratio"});
          RodMechanics m;
          m.rod = it.key();
          if (auto x = it->find("torsion_constant"); x != it->end())
            m.torsionConstant = positive(*x, member(ep, "torsion_constant"), "a torsion constant in mm^4");
          if (auto x = it->find("shear_factor"); x != it->end())
            m.shearFactor = positive(*x, member(ep, "shear_factor"), "a shear correction factor");
          if (auto x = it->find("poisson_ratio"); x != it->end())
            m.poissonRatio = ratio(*x, member(ep, "poisson_ratio"), "a Poisson ratio", -1.0, 0.5);
          spec.rods.push_back(std::move(m));
        }
      }
    }
    if (auto v = j.find("load_cases"); v != j.end()) loadCases(*v, member(path, "load_cases"), names, spec);
    return spec;
  }

  // ---- design optimization: training cases, targets and the "optimize" block ----

  // "load_cases": [{name, supports, loads, distributed_loads, load_steps, target, weight}]. The
  // supports and loads read as those at the top of the mechanics block (the same code, on a copy
  // holding only them); load_steps defaults to the block's.
  void loadCases(const json& j, const std::string& path, const std::map<std::string, std::string>& names, MechanicsSpec& spec) {
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
      const std::string cp = index(path, i);
      const json& c = j[i];
      if (!c.is_object()) {
        fail(cp, "expected a load case {name, supports, loads, distributed_loads, load_steps, target, weight}, got " + describe(c));
        continue;
      }
      onlyKeys(c, cp, {"name", "supports", "loads", "distributed_loads", "load_steps", "target", "weight"});
      LoadCase lc;
      lc.path = cp;
      if (auto n = require(c, cp, "name", "a case name (a non-empty string)"))
        if (auto name = string(*n, member(cp, "name"), "a case name")) {
          lc.name = *name;
          if (name->empty()) fail(member(cp, "name"), "expected a non-empty case name");
          else if (auto [it, fresh] = caseNames.emplace(*name, cp); !fresh)
            fail(member(cp, "name"), "duplicate load case name \"" + *name + "\" (also " + it->second + ")");
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
        if (auto x = number(*w, member(cp, "weight"), "a weight (a number >= 0)")) {
          if (*x < 0) fail(member(cp, "weight"), "expected a weight >= 0, got " + describe(*w));
          else lc.weight = *x;
        }
      if (auto t = c.find("target"); t != c.end()) target(*t, member(cp, "target"), names, lc);
      spec.loadCases.push_back(std::move(lc));
    }
  }

  // "target": {"design": PATH} (read by readDesign, relative to the design file) or
  // {"rods": {NAME: {centerline, orientation | normal}}}.
  void target(const json& j, const std::string& path, const std::map<std::string, std::string>& names, LoadCase& lc) {
    if (!j.is_object() || j.size() != 1 || !(j.contains("design") || j.contains("rods"))) {
      fail(path, "expected {\"design\": PATH} or {\"rods\": {ROD NAME: {centerline, orientation}}}, got " + describe(j));
      return;
    }
    if (auto d = j.find("design"); d != j.end()) {
      if (auto file = string(*d, member(path, "design"), "a design file's path, relative to this design")) {
        if (file->empty()) fail(member(path, "design"), "expected a non-empty path");
        else lc.targetDesign = *file;
      }
      return;
    }
    const json& rods = j["rods"];
    const std::string rp = member(path, "rods");
    if (!rods.is_object() || rods.empty()) {
      fail(rp, "expected a non-empty object {ROD NAME: {centerline, orientation}}, got " + describe(rods));
      return;
    }
    for (auto it = rods.begin(); it != rods.end(); ++it) {
      const std::string ep = member(rp, it.key());
      if (!names.count(it.key())) {
        fail(ep, "no rod is named \"" + it.key() + "\"");
        continue;
      }
      if (auto t = targetRod(*it, ep)) {
        t->rod = it.key();
        lc.target.push_back(std::move(*t));
      }
    }
  }

  // One target rod: a centerline and optionally its frames ("orientation" or "normal").
  std::optional<TargetRod> targetRod(const json& j, const std::string& path) {
    if (!j.is_object()) {
      fail(path, "expected a target {centerline, orientation}, got " + describe(j));
      return std::nullopt;
    }
    onlyKeys(j, path, {"centerline", "orientation", "normal"});
    const std::size_t before = issues.size();
    TargetRod t;
    t.path = path;
    std::optional<NurbsCurve> curve;
    if (auto c = require(j, path, "centerline", "a NURBS curve {degree, knots, points, weights}")) curve = centerline(*c, member(path, "centerline"));
    if (j.contains("orientation") && j.contains("normal")) fail(path, "give either \"normal\" or \"orientation\", not both");
    if (auto o = j.find("orientation"); o != j.end()) t.orientation = orientation(*o, member(path, "orientation"), curve ? &*curve : nullptr);
    if (auto n = j.find("normal"); n != j.end()) {
      t.referenceNormal = vector3(*n, member(path, "normal"), "a reference normal");
      if (t.referenceNormal && !(t.referenceNormal->cwiseAbs().maxCoeff() > 0.0)) fail(member(path, "normal"), "the reference normal must not be zero");
    }
    if (!curve || issues.size() != before) return std::nullopt;
    t.centerline = std::move(*curve);
    return t;
  }

  // The top-level "optimize" block.
  OptimizeSpec optimize(const json& j, const std::string& path) {
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
        if (auto x = number(*v, member(path, key), "a weight (a number >= 0)")) {
          if (*x < 0) fail(member(path, key), "expected a weight >= 0, got " + describe(*v));
          else out = *x;
        }
    };
    weight("position_weight", spec.positionWeight);
    weight("curvature_weight", spec.curvatureWeight);
    const auto integer = [&](const char* key, long long lo, long long hi, int& out) {
      if (auto v = j.find(key); v != j.end()) {
        if (!v->is_number_integer() || v->get<long long>() < lo || v->get<long long>() > hi)
          fail(member(path, key), "expected an integer from " + std::to_string(lo) + " to " + std::to_string(hi) + ", got " + describe(*v));
        else out = v->get<int>();
      }
    };
    integer("modulus_controls", 2, 64, spec.modulusControls);
    integer("modulus_degree", 1, kMaxDegree, spec.modulusDegree);
    integer("max_iterations", 0, 100000, spec.maxIterations);
    if (auto v = j.find("tolerance"); v != j.end())
      if (auto x = number(*v, member(path, "tolerance"), "a tolerance (a number >= 0)")) {
        if (*x < 0) fail(member(path, "tolerance"), "expected a tolerance >= 0, got " + describe(*v));
        else spec.tolerance = *x;
      }
    if (auto v = j.find("bounds_mpa"); v != j.end()) {
      const std::string bp = member(path, "bounds_mpa");
      if (!v->is_array() || v->size() != 2) {
        fail(bp, "expected [lowest, highest] Young's modulus in MPa, got " + describe(*v));
      } else {
        auto lo = youngsModulus((*v)[0], index(bp, 0)), hi = youngsModulus((*v)[1], index(bp, 1));
        if (lo && hi && !(*lo < *hi)) fail(bp, "expected the lowest modulus below the highest, got " + describe(*v));
        else if (lo && hi) spec.boundsMpa = std::make_pair(*lo, *hi);
      }
    }
    return spec;
  }
};

using ordered = nlohmann::ordered_json;

ordered curveJson(int degree, const std::vector<double>& knots) { return ordered{{"degree", degree}, {"knots", knots}}; }

ordered vec3Json(const Vec3& v) { return ordered::array({v.x(), v.y(), v.z()}); }

ordered endRefJson(const RodEndRef& ref) {
  if (ref.point) return ordered{{"point", vec3Json(*ref.point)}};
  if (ref.parameter) return ordered{{"rod", ref.rod}, {"parameter", *ref.parameter}};
  return ordered{{"rod", ref.rod}, {"end", ref.end == RodEnd::Start ? "start" : "end"}};
}

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
  for (const PointLoad& l : spec.loads)
    loads.push_back({{"at", endRefJson(l.at)}, {"force", vec3Json(l.force)}, {"moment", vec3Json(l.moment)}});
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

DesignError::DesignError(std::string file, std::vector<DesignIssue> issues)
    : std::runtime_error(formatIssues(file, issues)), file_(std::move(file)), issues_(std::move(issues)) {}

RodStructure parseDesign(const std::string& text, const std::string& sourceName) {
  json doc;
  try {
    doc = common::parseJsonStrict(tagOverflowingNumbers(text));
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
  Validator v;
  RodStructure structure;
  structure.source = sourceName;
  if (!doc.is_object()) throw DesignError(sourceName, {{"", "expected a JSON object with \"format\" and \"rods\""}});
  v.onlyKeys(doc, "", {"format", "units", "rods", "description", "metadata", "mechanics", "optimize"});
  if (auto f = v.require(doc, "", "format", std::string("\"") + kDesignFormat + "\"")) {
    if (!f->is_string() || *f != kDesignFormat)
      v.fail("format", "unsupported format " + describe(*f) + " (this rodfab reads \"" + kDesignFormat + "\")");
  }
  if (auto u = doc.find("units"); u != doc.end() && *u != "mm")
    v.fail("units", "expected \"mm\" (designs are in millimetres), got " + describe(*u));
  if (auto d = doc.find("description"); d != doc.end() && !d->is_string())
    v.fail("description", "expected a string, got " + describe(*d));
  if (auto rods = v.require(doc, "", "rods", "a non-empty array of rods")) {
    if (!rods->is_array() || rods->empty()) {
      v.fail("rods", "expected a non-empty array of rods, got " + describe(*rods));
    } else {
      std::map<std::string, std::string> names;
      for (std::size_t i = 0; i < rods->size(); ++i)
        if (auto r = v.rod((*rods)[i], index("rods", i), names)) structure.rods.push_back(std::move(*r));
      if (auto m = doc.find("mechanics"); m != doc.end()) structure.mechanics = v.mechanics(*m, "mechanics", names);
    }
  }
  if (auto o = doc.find("optimize"); o != doc.end()) structure.optimize = v.optimize(*o, "optimize");
  if (!v.issues.empty()) throw DesignError(sourceName, std::move(v.issues));
  return structure;
}

namespace {

// The rods of a load case's {"design": PATH} target: the rods of that design (its own targets are
// not followed) that carry names of this one.
void resolveTargetDesigns(RodStructure& structure, const std::filesystem::path& file) {
  std::vector<DesignIssue> issues;
  for (LoadCase& lc : structure.mechanics.loadCases) {
    if (lc.targetDesign.empty()) continue;
    const std::string where = lc.path + ".target.design";
    const std::filesystem::path targetFile = file.parent_path() / lc.targetDesign;
    RodStructure target;
    try {
      target = parseDesign(common::readBoundedFile(targetFile.string()), targetFile.string());
    } catch (const common::JsonInputError& e) {
      issues.push_back({where, "cannot read the target design " + targetFile.string() + ": " + e.message});
      continue;
    } catch (const DesignError& e) {
      issues.push_back({where, "the target design is not valid: " + std::string(e.what())});
      continue;
    }
    lc.target.clear();
    for (std::size_t i = 0; i < target.rods.size(); ++i) {
      const Rod& r = target.rods[i];
      const bool known = std::any_of(structure.rods.begin(), structure.rods.end(), [&](const Rod& d) { return d.name() == r.name(); });
      if (!known) {
        issues.push_back({where, targetFile.string() + ": rods[" + std::to_string(i) + "]: the target's rod \"" + r.name() +
                                     "\" is not in this design (targets match rods by name)"});
        continue;
      }
      lc.target.push_back({r.name(), r.centerline(), r.orientation(), r.referenceNormal(),
                           targetFile.string() + ": rods[" + std::to_string(i) + "]"});
    }
  }
  if (!issues.empty()) throw DesignError(structure.source, std::move(issues));
}

}  // namespace

RodStructure readDesign(const std::filesystem::path& file) {
  std::string text;
  try {
    text = common::readBoundedFile(file.string());
  } catch (const common::JsonInputError& e) {
    throw DesignError(file.string(), {{"", e.message}});
  }
  RodStructure structure = parseDesign(text, file.string());
  resolveTargetDesigns(structure, file);
  return structure;
}

nlohmann::ordered_json designToJson(const RodStructure& structure, const std::string& description) {
  ordered rods = ordered::array();
  for (const Rod& rod : structure.rods) {
    ordered r{{"name", rod.name()}, {"centerline", nurbsJson(rod.centerline())}};
    const Section& s = rod.section();
    if (s.shape == SectionShape::Circle) r["section"] = {{"shape", "circle"}, {"diameter", s.width}};
    else r["section"] = {{"shape", std::string(toString(s.shape))}, {"width", s.width}, {"height", s.height}};
    if (rod.referenceNormal()) {
      const Vec3& n = *rod.referenceNormal();
      r["normal"] = {n.x(), n.y(), n.z()};
    }
    if (rod.orientation()) r["orientation"] = quaternionSplineJson(*rod.orientation());
    if (rod.caps() == CapStyle::Flat) r["caps"] = "flat";
    const BSplineField& e = rod.modulus();
    if (e.isConstant()) {
      r["modulus"] = e.values().front();
    } else {
      ordered m = curveJson(e.degree(), e.knots());
      m["values"] = e.values();
      r["modulus"] = m;
    }
    rods.push_back(std::move(r));
  }
  ordered doc{{"format", kDesignFormat}, {"units", "mm"}};
  if (!description.empty()) doc["description"] = description;
  doc["rods"] = std::move(rods);
  if (structure.mechanics.present) doc["mechanics"] = mechanicsJson(structure.mechanics);
  if (structure.optimize.present) doc["optimize"] = optimizeJson(structure.optimize);
  return doc;
}

void writeDesign(const RodStructure& structure, const std::filesystem::path& file, const std::string& description) {
  const auto doc = designToJson(structure, description);
  std::ostringstream out;
  out << "{\n";
  for (auto it = doc.begin(); it != doc.end(); ++it) {
    if (it.key() == "rods" || it.key() == "mechanics") continue;
    out << "  " << ordered(it.key()).dump() << ": " << it.value().dump() << ",\n";
  }
  out << "  \"rods\": [\n";
  const auto& rods = doc["rods"];
  for (std::size_t i = 0; i < rods.size(); ++i) out << "    " << rods[i].dump() << (i + 1 < rods.size() ? ",\n" : "\n");
  out << "  ]";
  if (auto m = doc.find("mechanics"); m != doc.end()) out << ",\n  \"mechanics\": " << m->dump(2, ' ');
  out << "\n}\n";
  common::writeFileAtomically(file, out.str());
}

bool isDesignFile(const std::filesystem::path& file) {
  return common::fileStartsWith(file, "{", std::string("\"") + kDesignFormat + "\"", 256);
}

}  // namespace rodfab::geometry
