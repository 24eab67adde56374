// Errors that list every issue found in one input file, and their text: each issue at its place, one
// per line, `FILE: PLACE: MESSAGE` (just `FILE: MESSAGE` for an issue of the file as a whole). Shared
// by the readers that report every issue at once (designs, printer profiles, calibration data).
#pragma once

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::common {

// A bad input file: what() says what is wrong with it, file() names it as the user gave it.
class InputFileError : public std::runtime_error {
public:
  InputFileError(const std::string& text, std::string file) : std::runtime_error(text), file_(std::move(file)) {}
  const std::string& file() const { return file_; }

private:
  std::string file_;
};

// Every issue found in one file (a reader does not stop at the first); `text` is what() of them all.
template <class Issue>
class IssueListError : public InputFileError {
public:
  // By reference: the callers build `text` from the same file and issues in the same call.
  IssueListError(const std::string& text, const std::string& file, const std::vector<Issue>& issues)
      : InputFileError(text, file), issues_(issues) {}
  const std::vector<Issue>& issues() const { return issues_; }

private:
  std::vector<Issue> issues_;
};

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
