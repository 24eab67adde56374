// Reading design files: strict JSON, then every check of the format, units and values, each violation
// recorded at its JSON path (geometry/design_reader.hpp). The rods are read in design_rods.cpp; the
// blocks of higher stages by their stages, with the same DesignReader.
#include "geometry/design_reader.hpp"

#include "common/interrupt.hpp"
#include "common/json_input.hpp"
#include "common/located_issues.hpp"
#include "common/memory_budget.hpp"
#include "common/quoted_text.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
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
  constexpr std::size_t kPollBytes = std::size_t{4} << 20;  // ~15 ms of scanning between interrupt polls
  for (std::size_t at = 0, poll = kPollBytes; at < text.size();) {
    if (at >= poll) {  // a design of hundreds of MB scans for seconds
      common::throwIfInterrupted();
      poll = at + kPollBytes;
    }
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
    bool exponent = false;
    for (; end < text.size(); ++end) {
      const char d = text[end];
      if (d == 'e' || d == 'E') exponent = true;
      else if (!((d >= '0' && d <= '9') || d == '.' || d == '+' || d == '-')) break;
    }
    // Only a literal with an exponent, or with over 300 characters, can lie beyond a double (1.8e308):
    // the others are not converted. Converting all of them (a copy and strtod each) took 0.15-0.23 s of
    // reading the mesh-made torus's 18.7 MB design (1.05 M numbers), this scan 0.065 s.
    if (exponent || end - at > 300) {
      char* parsedEnd = nullptr;
      const double v = std::strtod(text.c_str() + at, &parsedEnd);  // the literal only if it ends at `end`
      if (parsedEnd == text.c_str() + end && !std::isfinite(v)) {
        out.append(text, copied, at - copied);
        out += json(std::string(kOverflowTag) + text.substr(at, end - at)).dump();
        copied = end;
      }
    }
    at = end;
  }
  if (copied == 0) return text;
  out.append(text, copied, std::string::npos);
  return out;
}

}  // namespace

std::string describe(const json& j) {
  if (const auto literal = overflowLiteral(j)) return *literal + " (beyond the range of a double)";
  return common::describeJson(j);
}

void DesignReader::fail(const std::string& path, const std::string& message) { common::listIssue(issues, DesignIssue{path, message}); }

void DesignReader::onlyKeys(const json& obj, const std::string& path, const std::set<std::string>& allowed) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    if (!allowed.count(it.key())) fail(memberPath(path, it.key()), common::unknownKeyMessage(allowed));
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
    static_assert(kMaxKnotMagnitude == 1e12, "the message below says 1e12");
    if (!(std::abs(*v) <= kMaxKnotMagnitude)) {
      fail(indexPath(path, i), "expected a knot value within +-1e12, got " + describe(j[i]) +
                                   " (rescale the parameter, e.g. to [0, 1])");
      ok = false;
      continue;
    }
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

std::optional<Eigen::Vector4d> DesignReader::quaternion(const json& j, const std::string& path) {
  if (!j.is_array() || j.size() != 4) {
    fail(path, "expected a quaternion [w, x, y, z], got " + describe(j));
    return std::nullopt;
  }
  Eigen::Vector4d c;
  bool ok = true;
  for (std::size_t k = 0; k < 4; ++k) {
    auto x = number(j[k], indexPath(path, k), "a number");
    if (x) c[k] = *x; else ok = false;
  }
  if (ok && !(c.cwiseAbs().maxCoeff() > 0.0)) {  // not c.norm(): 1e-170 would underflow to zero
    fail(path, "a zero quaternion has no rotation");
    ok = false;
  }
  return ok ? std::optional<Eigen::Vector4d>(c) : std::nullopt;
}

std::optional<std::string> DesignReader::string(const json& j, const std::string& path, const std::string& what) {
  if (!j.is_string()) {
    fail(path, "expected " + what + " (a string), got " + describe(j));
    return std::nullopt;
  }
  return j.get<std::string>();
}

std::optional<std::string> DesignReader::name(const json& j, const std::string& path, const std::string& what) {
  std::optional<std::string> s = string(j, path, what);
  if (!s) return std::nullopt;
  std::string problem;
  if (s->empty()) problem = "expected " + what + ", not an empty string";
  else if (s->size() > kMaxNameBytes)
    problem = "expected " + what + " of at most " + std::to_string(kMaxNameBytes) + " bytes, got " + std::to_string(s->size());
  else if (common::holdsControlCharacters(*s))
    problem = "expected " + what + " without control characters, got " + common::quotedFromFile(*s);
  if (problem.empty()) return s;
  fail(path, problem);
  return std::nullopt;
}


DesignError::DesignError(std::string file, std::vector<DesignIssue> issues)
    : IssueListError(common::formatLocatedIssues(file, issues), file, issues) {}

namespace {

// nlohmann's document of a design takes up to ~20 times its text (measured: 240 MB of numbers, 4.9 GB).
constexpr double kDocumentBytesPerTextByte = 24.0;

// The document of `text`; throws DesignError when it is not JSON, common::OutOfMemory (naming the
// file) when its document would not fit the memory budget.
json parseDocument(const std::string& text, const std::string& sourceName) {
  common::requireMemory(common::saturatedBytes(kDocumentBytesPerTextByte * static_cast<double>(text.size())),
                        {.what = "reading " + sourceName + " (" + common::formatBytes(text.size()) + " of JSON)",
                         .remedy = "split the design or raise --max-memory"});
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

struct ReadRod {
  std::size_t index;  // in "rods"
  RodParts parts;
};

// Builds the rods that read without issue, on as many threads as TBB may use (building is most of
// the reading: a winding rod takes milliseconds and up to ~1 MB), keeps them or only their summary. A
// rod's own failure (a centerline of zero length or too intricate to sample: at the rod's "centerline")
// is recorded right after that rod's issues (`issuesAfter[index]` of them came before it), so the list
// is in the file's order whatever the thread count, as are the summary's sums.
void buildRods(std::vector<ReadRod>& read, const std::vector<std::size_t>& issuesAfter, RodsKept kept, DesignReader& v,
               DesignDocument& d) {
  std::vector<std::optional<Rod>> built(kept == RodsKept::All ? read.size() : 0);
  std::vector<DesignSummary> summaries(read.size());
  std::vector<std::string> failures(read.size());
  std::vector<char> ofCenterline(read.size(), 0);  // the failure is the centerline's (CenterlineError)
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, read.size(), 1), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      common::throwIfInterrupted();
      RodParts& p = read[k].parts;
      try {
        Rod rod(std::move(p.name), std::move(p.centerline), p.section, std::move(p.referenceNormal), std::move(p.orientation), p.caps,
                std::move(p.modulus));
        summaries[k].add(rod);
        if (kept == RodsKept::All) built[k].emplace(std::move(rod));
      } catch (const CenterlineError& error) {
        failures[k] = error.what();
        ofCenterline[k] = 1;
      } catch (const std::invalid_argument& error) {
        failures[k] = error.what();
      }
    }
  });
  std::vector<DesignIssue> issues;
  std::size_t next = 0;
  const auto takeIssuesUpTo = [&](std::size_t end) {
    for (; next < end; ++next) common::listIssue(issues, std::move(v.issues[next]));
  };
  if (kept == RodsKept::All) d.structure.rods.reserve(read.size());
  for (std::size_t k = 0; k < read.size(); ++k) {
    takeIssuesUpTo(issuesAfter[read[k].index]);
    if (!failures[k].empty()) {
      const std::string rod = indexPath("rods", read[k].index);
      common::listIssue(issues, DesignIssue{ofCenterline[k] ? memberPath(rod, "centerline") : rod, failures[k]});
      continue;
    }
    d.summary.add(summaries[k]);
    if (kept == RodsKept::All) d.structure.rods.push_back(std::move(*built[k]));
  }
  takeIssuesUpTo(v.issues.size());
  v.issues = std::move(issues);
}

}  // namespace

DesignDocument parseDesignDocument(const std::string& text, const std::string& sourceName, DesignReader& v, RodsKept kept) {
  return readDesignDocument(parseDocument(text, sourceName), sourceName, v, kept);
}

DesignDocument readDesignDocument(json document, const std::string& sourceName, DesignReader& v, RodsKept kept) {
  DesignDocument d;
  d.json = std::move(document);
  d.structure.source = sourceName;
  const json& doc = d.json;
  if (!doc.is_object()) throw DesignError(sourceName, {{"", "expected a JSON object with \"format\" and \"rods\""}});
  v.onlyKeys(doc, "", {"written_by", "format", "units", "rods", "description", "metadata", "mechanics", "optimize"});
  if (auto f = v.require(doc, "", "format", std::string("\"") + kDesignFormat + "\"")) {
    if (!f->is_string() || *f != kDesignFormat)
      v.fail("format", "unsupported format " + describe(*f) + " (this rodfab reads \"" + kDesignFormat + "\")");
  }
  if (auto u = doc.find("units"); u != doc.end() && *u != "mm")
    v.fail("units", "expected \"mm\" (designs are in millimetres), got " + describe(*u));
  for (const char* text : {"description", "written_by"})  // written_by: rodfab's seal (design_file.hpp), read as text
    if (auto t = doc.find(text); t != doc.end() && !t->is_string()) v.fail(text, "expected a string, got " + describe(*t));
  if (auto rods = v.require(doc, "", "rods", "a non-empty array of rods")) {
    if (!rods->is_array() || rods->empty()) {
      v.fail("rods", "expected a non-empty array of rods, got " + describe(*rods));
    } else {
      d.rodsListed = true;
      std::vector<ReadRod> read;
      std::vector<std::size_t> issuesAfter(rods->size());
      for (std::size_t i = 0; i < rods->size(); ++i) {
        if (i % 1024 == 0) common::throwIfInterrupted();  // 30,000 rods take a second to check
        if (auto r = v.rod((*rods)[i], indexPath("rods", i), d.rodNames)) read.push_back({i, std::move(*r)});
        issuesAfter[i] = v.issues.size();
      }
      buildRods(read, issuesAfter, kept, v, d);
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

DesignSummary summarizeDesign(const std::string& text, const std::string& sourceName) {
  DesignReader reader;
  DesignDocument d = parseDesignDocument(text, sourceName, reader, RodsKept::SummaryOnly);
  if (!reader.issues.empty()) throw DesignError(sourceName, std::move(reader.issues));
  return d.summary;
}

DesignSummary summarizeDesignDocument(const nlohmann::ordered_json& document, const std::string& sourceName) {
  DesignReader reader;
  DesignDocument d = readDesignDocument(json(document), sourceName, reader, RodsKept::SummaryOnly);
  if (!reader.issues.empty()) throw DesignError(sourceName, std::move(reader.issues));
  return d.summary;
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
