// The IGES text checks (cad_checks.hpp, prescanIgesText): one pass over the 80-column records before
// OpenCASCADE's IGES reader loads them, for the counts it trusts.
#include "meshing/cad_checks.hpp"

#include "common/interrupt.hpp"
#include "common/quoted_text.hpp"

#include <Geom_BSplineCurve.hxx>
#include <Geom_BSplineSurface.hxx>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rodfab::meshing::detail {

namespace {

// The first `count` values of an IGES record, as written (spaces trimmed).
std::vector<std::string> leadingFields(const std::string& text, char delimiter, std::size_t count) {
  std::vector<std::string> fields;
  for (std::size_t at = 0; fields.size() < count && at <= text.size();) {
    const std::size_t end = std::min(text.find(delimiter, at), text.size());
    std::string field = text.substr(at, end - at);
    field.erase(0, field.find_first_not_of(' '));
    field.erase(field.find_last_not_of(' ') + 1);
    fields.push_back(field);
    at = end + 1;
  }
  return fields;
}

// The leading integers of an IGES entity's parameter text ("126,5,3,..." gives 126, 5, 3), up to the
// first field that does not start with one.
std::vector<long long> leadingIntegers(const std::string& text, char delimiter, std::size_t count) {
  std::vector<long long> values;
  for (const std::string& field : leadingFields(text, delimiter, count)) {
    char* stop = nullptr;
    const long long v = std::strtoll(field.c_str(), &stop, 10);
    if (stop == field.c_str()) break;
    values.push_back(v);
  }
  return values;
}

// The values an IGES B-spline's parameter record needs for its counts, up to its parameter range
// (the trailing normal of a planar curve is left out: writers may omit it). Type 126: the type, K, M
// and 4 flags, K + M + 2 knots, K + 1 weights, 3 (K + 1) coordinates, V(0) and V(1); type 128: the
// type, K1, K2, M1, M2 and 5 flags, both knot vectors, the weights and coordinates of the
// (K1 + 1)(K2 + 1) poles, U(0), U(1), V(0), V(1).
double igesSplineValues(bool curve, const std::vector<long long>& v) {
  if (curve) return 7.0 + double(v[1] + v[2] + 2) + 4.0 * double(v[1] + 1) + 2.0;
  return 10.0 + double(v[1] + v[3] + 2) + double(v[2] + v[4] + 2) + 4.0 * double(v[1] + 1) * double(v[2] + 1) + 4.0;
}

// An IGES B-spline's counts (type 126: upper index K, degree M; type 128: K1, K2, M1, M2) as
// OpenCASCADE's parameter reader takes them: it sizes and fills arrays from them unchecked, so a
// degree of a million writes far outside them while loading, and a record with fewer values than the
// counts need leaves arrays null that its Init then reads (both SIGSEGVs). `values`: the values the
// entity's parameter record holds.
void checkIgesSpline(const std::string& params, long long values, char delimiter, long long line, std::uintmax_t fileBytes,
                     const std::filesystem::path& file) {
  const std::vector<long long> v = leadingIntegers(params, delimiter, 5);
  if (v.empty() || (v[0] != 126 && v[0] != 128)) return;
  const bool curve = v[0] == 126;
  const int maxDegree = curve ? Geom_BSplineCurve::MaxDegree() : Geom_BSplineSurface::MaxDegree();
  const std::size_t directions = curve ? 1 : 2;
  if (v.size() < 1 + 2 * directions) return;  // too short: OpenCASCADE's reader records the failure
  for (std::size_t d = 0; d < directions; ++d) {
    const long long upper = v[1 + d], degree = v[1 + directions + d];
    std::string problem;
    if (degree < 1 || degree > maxDegree)
      problem = "degree " + std::to_string(degree) + ", expected 1 to " + std::to_string(maxDegree);
    else if (upper < degree || std::uintmax_t(upper) > fileBytes)
      problem = "upper pole index " + std::to_string(upper) + ", expected at least the degree " + std::to_string(degree) +
                " and no more than the file holds";
    if (!problem.empty())
      throw MeshError(file, "line " + std::to_string(line) + ": malformed IGES B-spline " + (curve ? "curve" : "surface") +
                                " (type " + std::to_string(v[0]) + "): " + problem);
  }
  if (const double needed = igesSplineValues(curve, v); double(values) < needed) {
    char text[160];
    std::snprintf(text, sizeof text, "%lld values where its counts need at least %.0f", values, needed);
    throw MeshError(file, "line " + std::to_string(line) + ": malformed IGES B-spline " + (curve ? "curve" : "surface") +
                              " (type " + std::to_string(v[0]) + "): " + text);
  }
}

// IGES B-rep entities whose record holds a count and then that many items: OpenCASCADE's reader fills
// its arrays for the count from whatever follows, and a count beyond the values there (or one that is
// not an integer: "E5") leaves items null that the transfer dereferences (a face of 100,000 loops in a
// record of 5 values, a SIGSEGV found by scripts/mutate_cad.py).
struct IgesListEntity {
  long long type;
  const char* name;
  std::size_t countField;  // which value of the record (0: the type) is the count
  long long fixed;         // values that are not items (the type and the count included)
  long long perItem;       // the fewest values an item takes
  const char* items;
};
constexpr IgesListEntity kIgesListEntities[] = {
    {186, "Manifold Solid", 3, 4, 2, "void shells"}, {502, "Vertex List", 1, 2, 3, "vertices"},
    {504, "Edge List", 1, 2, 5, "edges"},            {508, "Loop", 1, 2, 5, "edges"},
    {510, "Face", 2, 4, 1, "loops"},                 {514, "Shell", 1, 2, 2, "faces"}};

void checkIgesListCounts(const std::string& params, long long values, char delimiter, char recordEnd, long long line,
                         const std::filesystem::path& file) {
  const std::vector<std::string> fields = leadingFields(params.substr(0, params.find(recordEnd)), delimiter, 4);
  if (fields.empty()) return;
  for (const IgesListEntity& e : kIgesListEntities) {
    if (fields[0] != std::to_string(e.type)) continue;
    if (fields.size() <= e.countField) return;  // too short: OpenCASCADE's reader records the failure
    const std::string& count = fields[e.countField];
    const std::string where = "line " + std::to_string(line) + ": malformed IGES " + e.name + " (type " + std::to_string(e.type) + "): ";
    // An empty field is IGES's default, 0.
    if (count.size() > 18 || count.find_first_not_of("0123456789") != std::string::npos)
      throw MeshError(file, where + "its count of " + e.items + " " + common::quotedFromFile(count) + " is not a whole number");
    const long long n = count.empty() ? 0 : std::stoll(count);
    if (values < e.fixed + e.perItem * n)
      throw MeshError(file, where + std::to_string(n) + " " + e.items + " need at least " + std::to_string(e.fixed + e.perItem * n) +
                                " values; the record holds " + std::to_string(values));
    return;
  }
}

bool isLoopRecord(const std::string& params, char delimiter) {
  const std::vector<std::string> type = leadingFields(params, delimiter, 1);
  return !type.empty() && type[0] == "508";
}

// An IGES loop (type 508): N, then per edge its type, list, index, orientation and K, then K pairs
// (an isoparametric flag and a curve in the face's parameter space). OpenCASCADE's reader reads each
// edge's K pairs from whatever follows, and a K running past the record left a null curve it then
// dereferenced while loading (a SIGSEGV in IGESSolid_ToolLoop::ReadOwnParams, scripts/mutate_cad.py).
// The edge count itself is checkIgesListCounts'.
void checkIgesLoopEdges(const std::string& params, char delimiter, char recordEnd, long long line,
                        const std::filesystem::path& file) {
  if (!isLoopRecord(params, delimiter)) return;
  const std::vector<std::string> fields =
      leadingFields(params.substr(0, params.find(recordEnd)), delimiter, std::numeric_limits<std::size_t>::max());
  const auto whole = [](const std::string& f) { return f.size() <= 9 && f.find_first_not_of("0123456789") == std::string::npos; };
  if (fields.size() < 2 || !whole(fields[1])) return;  // checkIgesListCounts says so
  const long long edges = fields[1].empty() ? 0 : std::stoll(fields[1]);
  const std::string where = "line " + std::to_string(line) + ": malformed IGES Loop (type 508): edge ";
  std::size_t at = 2;
  for (long long e = 1; e <= edges; ++e) {
    if (at + 5 > fields.size()) throw MeshError(file, where + std::to_string(e) + " of " + std::to_string(edges) + " runs past the record");
    const std::string& curves = fields[at + 4];
    if (!whole(curves))
      throw MeshError(file, where + std::to_string(e) + ": its count of parameter-space curves " + common::quotedFromFile(curves) +
                                " is not a whole number");
    at += 5 + 2 * std::size_t(curves.empty() ? 0 : std::stoll(curves));
    if (at > fields.size())
      throw MeshError(file, where + std::to_string(e) + ": its " + curves + " parameter-space curves run past the record");
  }
}

// The Global section's unit flag (its 14th value, `text` being the section's columns 1-72): 1 to 11, the
// unit's code. A section that does not give it means inches to IGES and to OpenCASCADE, which says
// nothing: a file whose section was cut short or garbled before it (a string of length -5) became a
// design 25.4 times its size. The values before it are split leniently, as a reader that recovers
// would: a string nH... of n bytes when its end meets a delimiter, else everything up to the next one
// (a name counted in characters rather than UTF-8 bytes still finds the unit).
void checkIgesGlobalUnit(std::string_view text, char delimiter, char recordEnd, long long line, const std::filesystem::path& file) {
  constexpr int kUnitFlag = 14;
  const auto nextStop = [&](std::size_t from) { return std::min(text.find_first_of(std::string{delimiter, recordEnd}, from), text.size()); };
  std::size_t at = 0;
  for (int value = 1; at < text.size(); ++value) {
    at = std::min(text.find_first_not_of(' ', at), text.size());
    std::size_t end = nextStop(at);
    const std::size_t digitsEnd = std::min(text.find_first_not_of("0123456789", at), text.size());
    if (digitsEnd > at && digitsEnd - at <= 6 && digitsEnd < text.size() && text[digitsEnd] == 'H') {
      const std::size_t stringEnd = digitsEnd + 1 + std::stoul(std::string(text.substr(at, digitsEnd - at)));
      const std::size_t after = std::min(text.find_first_not_of(' ', stringEnd), text.size());
      if (stringEnd <= text.size() && after < text.size() && (text[after] == delimiter || text[after] == recordEnd)) end = after;
    }
    if (value == kUnitFlag) {
      std::string flag(text.substr(at, end - at));
      flag.erase(flag.find_last_not_of(' ') + 1);
      if (!flag.empty() && flag.size() <= 2 && flag.find_first_not_of("0123456789") == std::string::npos && std::stoi(flag) >= 1 &&
          std::stoi(flag) <= 11)
        return;
      throw MeshError(file, "line " + std::to_string(line) + ": the IGES Global section's unit flag (its value 14) is " +
                                (flag.empty() ? std::string("not given") : common::quotedFromFile(flag)) +
                                ", expected 1 to 11 (2: millimetres): without it IGES means inches, and the design would be "
                                "25.4 times the size a millimetre model has; export the file again with its unit");
    }
    if (end >= text.size() || text[end] == recordEnd) break;
    at = end + 1;
  }
  throw MeshError(file, "line " + std::to_string(line) + ": the IGES Global section ends before its unit flag (value 14), so IGES "
                        "would mean inches and the design could be 25.4 times its size; export the file again with its unit");
}

}  // namespace

void prescanIgesText(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw MeshError(file, "cannot open");
  std::error_code ec;
  const std::uintmax_t bytes = std::filesystem::file_size(file, ec);
  // Fixed 80-column records: the section letter in column 73; a parameter record holds data in columns
  // 1-64 and its entity's directory pointer in 65-72. The global section may declare another delimiter.
  char delimiter = ',', recordEnd = ';';
  bool firstGlobal = true, ended = false;
  std::string line, entity, params, global;
  long long globalLine = 0;
  long long number = 0, entityLine = 0, values = 0;
  char lastSection = 0;
  std::optional<MeshError> firstRecordProblem;  // thrown after the Terminate check: a file cut short says so
  const auto flush = [&] {
    try {
      if (!params.empty() && !firstRecordProblem) {
        checkIgesSpline(params, values, delimiter, entityLine, bytes, file);
        checkIgesListCounts(params, values, delimiter, recordEnd, entityLine, file);
        checkIgesLoopEdges(params, delimiter, recordEnd, entityLine, file);
      }
    } catch (const MeshError& e) {
      firstRecordProblem = e;
    }
    params.clear(), values = 1, ended = false;
  };
  // The values of an entity's record: its delimiters before the record's end, plus one.
  const auto countValues = [&](std::string_view data) {
    for (const char c : data) {
      if (ended) return;
      if (c == recordEnd) ended = true;
      else values += c == delimiter;
    }
  };
  while (std::getline(in, line)) {
    ++number;
    if (number % 4096 == 0) common::throwIfInterrupted();
    if (line.size() < 73) continue;
    lastSection = line[72];
    // A directory or parameter record's sequence number (columns 74-80) is a number: OpenCASCADE's
    // reader crashed on "000;017" in a directory entry (scripts/mutate_cad.py).
    if ((line[72] == 'D' || line[72] == 'P') && line.find_first_not_of("0123456789 \r", 73) != std::string::npos)
      throw MeshError(file, "line " + std::to_string(number) + ": malformed IGES record: its sequence number (columns 74-80) " +
                                common::quotedFromFile(line.substr(73, 7)) + " is not a number");
    if (line[72] == 'G' && firstGlobal) {
      firstGlobal = false;
      globalLine = number;
      std::size_t at = 0;  // the global section's first two values: the delimiters, "1H," and "1H;" or empty
      if (line.compare(0, 2, "1H") == 0) delimiter = line[2], at = 3;
      if (line[at] == delimiter && line.compare(at + 1, 2, "1H") == 0) recordEnd = line[at + 3];
    }
    if (line[72] == 'G' && global.size() < (std::size_t{1} << 20)) {
      global += line.substr(0, 72);
    } else if (line[72] == 'P') {
      const std::string owner = line.substr(64, 8);
      if (owner != entity) flush(), entity = owner, entityLine = number;
      // The counts come first; a loop's edges each hold a count of their own, so a loop is kept whole.
      if (params.size() < 256 || isLoopRecord(params, delimiter)) params += line.substr(0, 64);
      countValues(std::string_view(line).substr(0, 64));
    }
  }
  flush();
  // Every IGES file ends with its Terminate record; OpenCASCADE's reader crashes on some files cut
  // short (an interrupted copy), inside their parameter records (scripts/mutate_cad.py). A file without
  // any record is not IGES at all, which the reader says.
  if (lastSection != 0 && lastSection != 'T')
    throw MeshError(file, "the file ends without IGES's Terminate record (a 'T' in column 73 of its last line): it was cut "
                          "short, perhaps by an interrupted copy; copy or export it again");
  if (globalLine > 0) checkIgesGlobalUnit(global, delimiter, recordEnd, globalLine, file);
  if (firstRecordProblem) throw *firstRecordProblem;
}

}  // namespace rodfab::meshing::detail
