// The text mesh checks (text_mesh_checks.hpp): OFF and OBJ as CGAL's readers take them, binary STL's
// count and numbers, and the copy with what those readers would misread changed.
#include "meshing/text_mesh_checks.hpp"

#include "common/quoted_text.hpp"
#include "meshing/mesh.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <regex>
#include <sstream>
#include <string_view>
#include <vector>

namespace rodfab::meshing::detail {

namespace {

// The next line of `in` that holds something other than a comment, with the comment cut off.
bool nextContentLine(std::istream& in, std::string& line, int& number) {
  while (std::getline(in, line)) {
    ++number;
    line = line.substr(0, line.find('#'));
    if (line.find_first_not_of(" \t\r\x1a") != std::string::npos) return true;  // 0x1a: a DOS end-of-file mark
  }
  return false;
}

}  // namespace

// Text OFF is checked before CGAL reads it: its reader sizes arrays from the header's counts, and
// casts each face's corner count from a double to size_t unchecked (undefined behaviour for 1e114 or
// -1, found by fuzzing), and reads a face's colour from the entries after its corners without checking
// they are there (a heap overflow when a line holds fewer numbers than its corner count says, found by
// fuzzing). So: counts the file's bytes can hold (a vertex takes at least 6 bytes of text, a face 8);
// every vertex line holds at least 3 numbers; every face line starts with a corner count of 3 to
// 1,000,000 and holds that many indices of existing vertices (CGAL casts them unchecked too) plus 0, 1,
// 3 or 4 colour entries. Vertex lines are taken one per line, as every OFF writer puts them.
void checkOffText(const std::string& bytes, const std::string& source) {
  std::istringstream in(bytes);
  std::string line;
  int number = 0;
  if (!nextContentLine(in, line, number)) return;
  std::istringstream head(line);
  std::string word, rest;
  head >> word;
  // CGAL takes any first word holding "OFF", even with bytes glued to it, and "SKEL" (a skeleton of
  // polylines, read unchecked: a polyline of 500 M points took 18 s and 3.9 GB); only the standard
  // keywords ([ST][C][N][4][n]OFF) are let through, so this check reads the counts where CGAL does.
  if (!std::regex_match(word, std::regex("(ST)?C?N?4?n?OFF")))
    throw MeshError(source, "OFF line " + std::to_string(number) + ": " + common::quotedFromFile(word) + " is not an OFF keyword");
  // nOFF puts a dimension before the counts, which CGAL reads as integers while this check read the
  // counts from it (a face of 5e10 corners reached CGAL: fuzz_mesh_reader, 2026-12-05); meshes here are 3D.
  if (word.find('n') != std::string::npos)
    throw MeshError(source, "OFF line " + std::to_string(number) + ": " + common::quotedFromFile(word) +
                                " (OFF of n dimensions) is not read: rods need a 3D mesh; write it as OFF");
  if (!(head >> rest) && !(nextContentLine(in, line, number) && (head = std::istringstream(line), head >> rest))) return;
  if (rest == "BINARY") return;  // binary counts: CGAL reads them as integers
  // The counts as every OFF writer puts them: vertices, faces, edges on one line (CGAL reads them as
  // tokens across lines, which would put this check out of step with it).
  double nv = -1, nf = -1, ne = -1;
  std::string extra;
  if (!(std::istringstream(rest) >> nv) || !(head >> nf >> ne) || (head >> extra) || nv != std::floor(nv) ||
      nf != std::floor(nf) || ne != std::floor(ne))
    throw MeshError(source, "OFF line " + std::to_string(number) + ": expected the vertex, face and edge counts on one line");
  if (nv < 0 || nf < 0 || nv * 6 + nf * 8 > static_cast<double>(bytes.size()) + 64)
    throw MeshError(source, "the OFF header declares " + rest + " vertices and more faces than the file's " +
                                std::to_string(bytes.size()) + " bytes can hold");
  const auto where = [&] { return "OFF line " + std::to_string(number) + ": "; };
  // The line's leading numbers, as CGAL's stream reads them; one it cannot hold is named.
  auto numbers = [&](const std::string& text) {
    std::istringstream words(text);
    std::vector<double> out;
    for (std::string token; words >> token;) {
      char* end = nullptr;
      const double d = std::strtod(token.c_str(), &end);
      if (end == token.c_str()) break;
      if (!std::isfinite(d)) throw MeshError(source, where() + common::quotedFromFile(token) + " " + kNotFinite);
      out.push_back(d);
    }
    return out;
  };
  for (double v = 0; v < nv; ++v) {
    if (!nextContentLine(in, line, number)) return;
    if (numbers(line).size() < 3) throw MeshError(source, where() + "a vertex needs 3 coordinates");
  }
  double facesRead = 0;
  for (; facesRead < nf && nextContentLine(in, line, number); ++facesRead) {
    const std::vector<double> entries = numbers(line);
    const double corners = entries.empty() ? 0 : entries[0];
    if (!(corners >= 3 && corners <= 1e6) || corners != std::floor(corners))
      throw MeshError(source, where() + "a face's corner count must be a whole number from 3 to 1000000");
    for (std::size_t k = 1; k <= static_cast<std::size_t>(corners) && k < entries.size(); ++k)
      if (!(entries[k] >= 0 && entries[k] < nv) || entries[k] != std::floor(entries[k]))
        throw MeshError(source, where() + "a face refers to a vertex that is not one of the " + rest);
    const double colours = static_cast<double>(entries.size()) - 1 - corners;
    if (colours != 0 && colours != 1 && colours != 3 && colours != 4)
      throw MeshError(source, where() + "a face of " + std::to_string(static_cast<long>(corners)) + " corners needs as many " +
                                  "indices (and 0, 1, 3 or 4 colour entries)");
  }
  // CGAL stops at the declared count: faces past it (a stale count) were dropped without a word.
  if (facesRead == nf && nextContentLine(in, line, number))
    throw MeshError(source, where() + "more lines follow the " + std::to_string(static_cast<long long>(nf)) +
                                " faces the header declares: its face count is smaller than the file's (nothing was read)");
}

namespace {

// Calls f(line) for every line of `bytes`, without its line break and trailing white space.
template <typename F>
void forEachLine(std::string_view bytes, const F& f) {
  while (!bytes.empty()) {
    const std::size_t eol = std::min(bytes.find('\n'), bytes.size());
    std::string_view line = bytes.substr(0, eol);
    line = line.substr(0, line.find_last_not_of(" \t\r") + 1);
    f(line);
    bytes.remove_prefix(std::min(eol + 1, bytes.size()));
  }
}

// A line's first word (CGAL's `iss >> s`) and what follows it.
std::pair<std::string_view, std::string_view> keyword(std::string_view line) {
  const std::size_t begin = std::min(line.find_first_not_of(" \t\r"), line.size());
  const std::size_t end = std::min(line.find_first_of(" \t\r", begin), line.size());
  return {line.substr(begin, end - begin), line.substr(end)};
}

}  // namespace

// CGAL's OBJ reader reads a face's corners as `int`s, each up to the next space, and stops at the
// first one it cannot read: a vertex number past 2^31 or a word silently shortens the face, and a number
// beyond the vertices only fails the whole file. Every face line is checked the way that reader takes
// it (tabs are spaces by then: see parseMesh), so the message names the line and the corner.
void checkObjFaces(const std::string& bytes, const std::string& source) {
  std::uint64_t vertices = 0, seen = 0;
  forEachLine(bytes, [&](std::string_view line) { vertices += keyword(line).first == "v"; });
  int number = 0;
  forEachLine(bytes, [&](std::string_view line) {
    ++number;
    auto [word, rest] = keyword(line);
    seen += word == "v";
    if (word != "f") return;
    const auto where = [&] { return "OBJ line " + std::to_string(number) + ": "; };
    rest = rest.substr(0, rest.find('#'));
    rest.remove_prefix(std::min(rest.find_first_not_of(" \t\r"), rest.size()));
    int corners = 0;
    for (std::size_t at = 0; (at = rest.find_first_not_of(" \r", at)) != std::string_view::npos; ++corners) {
      std::string_view corner = rest.substr(at, rest.find(' ', at) - at);
      at += corner.size();
      const std::string shown = common::quotedFromFile(corner);
      if (corner.starts_with('+')) corner.remove_prefix(1);
      long long index = 0;
      const auto [end, error] = std::from_chars(corner.data(), corner.data() + corner.size(), index);
      if (end == corner.data() || (error == std::errc{} && end != corner.data() + corner.size() && *end != '/'))
        throw MeshError(source, where() + "face corner " + shown + " is not a vertex number");
      if (error != std::errc{} || index == 0 || index > std::numeric_limits<int>::max() ||
          (index > 0 && std::uint64_t(index) > vertices) || (index < 0 && std::uint64_t(-index) > seen))
        throw MeshError(source, where() + "face corner " + shown + " names no vertex: expected 1 .. " + std::to_string(vertices) +
                                    " (or -1 .. -" + std::to_string(seen) + ", counted back from this line)");
    }
    if (corners < 3) throw MeshError(source, where() + "a face with " + std::to_string(corners) + " corners (expected 3 or more)");
  });
}

namespace {

// Text STL starts with "solid" and is text throughout; a binary header may start with "solid" too, but
// its triangles' floats soon hold bytes no text has.
bool looksLikeTextStl(const std::string& bytes) {
  const std::size_t begin = std::min(bytes.find_first_not_of(" \t\r\n"), bytes.size());
  if (bytes.compare(begin, 5, "solid") != 0) return false;
  const std::size_t end = std::min<std::size_t>(bytes.size(), 1024);
  return std::none_of(bytes.begin() + static_cast<std::ptrdiff_t>(begin), bytes.begin() + static_cast<std::ptrdiff_t>(std::max(begin, end)), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u == 0 || (u < 32 && !std::isspace(u)) || u == 127;
  });
}

}  // namespace

// CGAL's STL reader merges corners through an ordered map, which a NaN corrupts (it compares equal to
// everything): check a binary STL's floats before it is read.
void checkBinaryStlNumbers(const std::string& bytes, const std::string& source) {
  if (bytes.size() < 84 || looksLikeTextStl(bytes)) return;
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  const std::uint64_t declared = 84 + 50 * std::uint64_t(count);
  // CGAL reads `count` triangles and ignores the rest: triangles past a stale count were dropped
  // without a word, and a truncated file failed saying nothing of why. A few bytes of padding pass.
  if (bytes.size() < declared || bytes.size() >= declared + 50)
    throw MeshError(source, std::string(bytes.compare(0, 5, "solid") == 0 ? "neither a text STL (it starts with \"solid\" but holds bytes "
                                                                           "no text has) nor a " : "") +
                                "binary STL: its header declares " + std::to_string(count) + " triangles (" + std::to_string(declared) +
                                " bytes), but the file holds " + std::to_string(bytes.size()) + " bytes: " +
                                (bytes.size() > declared ? "the count is smaller than the data" : "was it cut short?") + " (nothing was read)");
  for (std::uint32_t t = 0; t < count; ++t)
    for (int k = 3; k < 12; ++k) {  // the 9 corner coordinates after the normal
      float v = 0;
      std::memcpy(&v, bytes.data() + 84 + 50 * std::size_t(t) + 4 * k, 4);
      if (!std::isfinite(v))
        throw MeshError(source, "triangle " + std::to_string(t) + " has a coordinate that is not a finite number");
    }
}

namespace {
constexpr std::string_view kUtf8Mark = "\xEF\xBB\xBF";

}  // namespace

// What CGAL's readers would misread, changed in a copy (empty when nothing needs to change): a UTF-8
// byte order mark before a text format (it glued to the first keyword: vertex 1 was lost, and a face
// 99 lines on was blamed); in OBJ, tabs (its reader skips a face corner up to the next space, so a
// tab-separated face lost corners) and line elements "l" (polylines, no surface: the reader failed the
// whole file), made comments.
std::string readerCopy(const std::string& bytes, const std::string& format) {
  // A text STL's mark too (its "solid" then read as a binary count); never a binary STL's header bytes.
  const bool mark = bytes.starts_with(kUtf8Mark) && (format != "stl" || looksLikeTextStl(bytes.substr(kUtf8Mark.size(), 1024)));
  const std::string_view body = std::string_view(bytes).substr(mark ? kUtf8Mark.size() : 0);
  const bool obj = format == "obj";
  const bool tabs = obj && body.find('\t') != std::string_view::npos;
  bool lines = false;  // a line whose first word (as CGAL reads it, after blanks) is "l"
  if (obj) forEachLine(body, [&](std::string_view line) { lines = lines || keyword(line).first == "l"; });
  if (!mark && !tabs && !lines) return {};
  std::string text(body);
  if (tabs) std::replace(text.begin(), text.end(), '\t', ' ');
  if (lines)
    for (std::size_t at = 0; at < text.size(); at = std::min(text.find('\n', at), text.size()) + 1) {
      const std::size_t word = std::min(text.find_first_not_of(" \r", at), text.size());
      if (text.compare(word, 2, "l ") == 0 || (text.compare(word, 1, "l") == 0 && (word + 1 == text.size() || text[word + 1] == '\n')))
        text[word] = '#';
    }
  return text;
}

}  // namespace rodfab::meshing::detail
