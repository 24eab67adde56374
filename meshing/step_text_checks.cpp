// The STEP text checks (cad_checks.hpp, prescanStepText): one pass over the file before OpenCASCADE's
// STEP parser reads it, for what it cannot take (nesting, list lengths, ids, empty lists, ids defined
// twice), named by line.
#include "meshing/cad_checks.hpp"

#include "common/interrupt.hpp"

#include <algorithm>
#include <fstream>
#include <string>
#include <string_view>
#include <unordered_set>
#include <vector>

namespace rodfab::meshing::detail {

namespace {

// Entities on whose empty lists OpenCASCADE's reader crashes (an empty knot, coordinate, trim or edge
// list is a SIGSEGV in its load check or its transfer: found emptying each list of the seed models in
// turn, 2026-12-05), with the other kinds of B-spline and surface curve. The STEP schema (ISO 10303-42)
// gives each of their lists at least one element, so no valid file has one.
constexpr std::string_view kNoEmptyLists[] = {
    "B_SPLINE_CURVE", "B_SPLINE_CURVE_WITH_KNOTS", "BEZIER_CURVE", "UNIFORM_CURVE", "QUASI_UNIFORM_CURVE",
    "RATIONAL_B_SPLINE_CURVE", "B_SPLINE_SURFACE", "B_SPLINE_SURFACE_WITH_KNOTS", "BEZIER_SURFACE", "UNIFORM_SURFACE",
    "QUASI_UNIFORM_SURFACE", "RATIONAL_B_SPLINE_SURFACE", "DIRECTION", "TRIMMED_CURVE", "SURFACE_CURVE", "SEAM_CURVE",
    "INTERSECTION_CURVE", "EDGE_LOOP"};

// The index of `word` in kNoEmptyLists, or -1.
int noEmptyListsIndex(std::string_view word) {
  const auto* found = std::find(std::begin(kNoEmptyLists), std::end(kNoEmptyLists), word);
  return found == std::end(kNoEmptyLists) ? -1 : static_cast<int>(found - std::begin(kNoEmptyLists));
}

// The scanner's state between two blocks of the file.
struct StepScan {
  long long line = 1;
  int depth = 0;
  bool inString = false, inComment = false;
  char previous = 0;
  bool inId = false;  // after '#', reading digits
  long long id = 0;
  bool idEnded = false;  // an id just read outside any list: a definition if '=' follows
  std::unordered_set<long long> defined;  // ids of the entities defined so far ("#12 = ...")
  long long commas[kMaxStepNesting + 1] = {};  // in the open list at each depth
  double squares = 0;                          // sum of the closed lists' lengths squared
  std::string word;                            // the keyword being read (the entity type before its '(')
  // Of the open list at each depth: the kNoEmptyLists entity whose parameters hold it (-1: none), whether
  // it is a list value (not an entity's parameter list) and whether it is still empty.
  int owner[kMaxStepNesting + 1] = {-1};
  bool listValue[kMaxStepNesting + 1] = {};
  bool empty[kMaxStepNesting + 1] = {};
};

void openList(StepScan& s) {
  s.empty[s.depth - 1] = false;
  s.listValue[s.depth] = s.word.empty();
  s.owner[s.depth] = s.word.empty() ? s.owner[s.depth - 1] : noEmptyListsIndex(s.word);
  s.empty[s.depth] = true;
}

void closeList(StepScan& s, const std::filesystem::path& file) {
  if (s.listValue[s.depth] && s.empty[s.depth] && s.owner[s.depth] >= 0)
    throw MeshError(file, "line " + std::to_string(s.line) + ": an empty list in a " +
                              std::string(kNoEmptyLists[s.owner[s.depth]]) +
                              ", where STEP requires at least one element (OpenCASCADE's reader crashes on it)");
}

// Keywords: letters, digits and '_' (whitespace may follow before the '('); anything else ends one.
void trackWord(StepScan& s, char c) {
  if ((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_') {
    if (s.word.size() < 64) s.word.push_back(c);
  } else if (c != ' ' && c != '\n' && c != '\r' && c != '\t' && c != '(') {
    s.word.clear();
  }
}

void scanChar(StepScan& s, char c, const std::filesystem::path& file) {
  if (c == '\n') ++s.line;
  if (s.inId) {
    if (c >= '0' && c <= '9') {
      s.id = s.id * 10 + (c - '0');
      if (s.id > kMaxStepEntityId)
        throw MeshError(file, "line " + std::to_string(s.line) + ": an entity id above " +
                                  std::to_string(kMaxStepEntityId) + " (OpenCASCADE reads ids as 32-bit integers)");
      return;
    }
    s.inId = false;
    s.idEnded = s.depth == 0;
  }
  const bool comment = s.inComment || c == '/' || (c == '*' && s.previous == '/');  // "#23 /* moved */ = ..." too
  if (s.idEnded && !comment && c != ' ' && c != '\n' && c != '\r' && c != '\t') {
    // OpenCASCADE keeps the first of two definitions of one id and says nothing: edges ended at the
    // wrong point (a box's corner left open, exit 0).
    s.idEnded = false;
    if (c == '=' && !s.defined.insert(s.id).second)
      throw MeshError(file, "line " + std::to_string(s.line) + ": entity #" + std::to_string(s.id) +
                                " is defined a second time (STEP gives every entity one id; which one was meant cannot be told)");
  }
  if (s.inComment) {
    if (s.previous == '*' && c == '/') s.inComment = false, c = 0;  // "*/*" must not reopen
  } else if (s.inString) {
    s.inString = c != '\'';  // a doubled '' leaves and re-enters: the same for counting
  } else {
    if (c != ' ' && c != '\n' && c != '\r' && c != '\t' && c != ')' && c != '(') s.empty[s.depth] = false;
    trackWord(s, c);
    if (c == '\'') {
      s.inString = true;
    } else if (s.previous == '/' && c == '*') {
      s.inComment = true, c = 0;
    } else if (c == '#') {
      s.inId = true, s.id = 0;
    } else if (c == '(') {
      if (++s.depth > kMaxStepNesting)
        throw MeshError(file, "line " + std::to_string(s.line) + ": lists nested deeper than " +
                                  std::to_string(kMaxStepNesting) + " levels");
      s.commas[s.depth] = 0;
      openList(s);
      s.word.clear();
    } else if (c == ',' && s.depth > 0 && ++s.commas[s.depth] >= kMaxStepListLength) {
      throw MeshError(file, "line " + std::to_string(s.line) + ": a list of more than " + std::to_string(kMaxStepListLength) +
                                " elements (OpenCASCADE's parser takes time growing with the square of a list's length)");
    } else if (c == ')' && s.depth > 0) {
      closeList(s, file);
      const double length = double(s.commas[s.depth--]) + 1;
      if ((s.squares += length * length) > kMaxStepListSquares)
        throw MeshError(file, "line " + std::to_string(s.line) + ": too many long lists for OpenCASCADE's parser (its time grows "
                                  "with the square of each list's length)");
    }
  }
  s.previous = c;
}

}  // namespace

void prescanStepText(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw MeshError(file, "cannot open");
  StepScan scan;
  std::vector<char> block(1 << 20);
  while (in.read(block.data(), std::streamsize(block.size())) || in.gcount() > 0) {
    common::throwIfInterrupted();
    for (std::streamsize i = 0; i < in.gcount(); ++i) scanChar(scan, block[std::size_t(i)], file);
  }
}

}  // namespace rodfab::meshing::detail
