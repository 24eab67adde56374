// The text of an error that lists every issue found in one input file, each at its place, one per
// line: `FILE: PLACE: MESSAGE` (just `FILE: MESSAGE` for an issue of the file as a whole). Shared by
// the readers that report every issue at once (designs, printer profiles).
#pragma once

#include <string>
#include <vector>

namespace rodfab::common {

// `Issue` has `path` (a JSON path such as `rods[3].centerline`, empty for the whole file) and `message`.
template <class Issue>
std::string formatLocatedIssues(const std::string& file, const std::vector<Issue>& issues) {
  std::string out;
  for (std::size_t i = 0; i < issues.size(); ++i) {
    if (i) out += '\n';
    out += file + ": ";
    if (!issues[i].path.empty()) out += issues[i].path + ": ";
    out += issues[i].message;
  }
  return out;
}

}  // namespace rodfab::common
