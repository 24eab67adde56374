// Errors that list every issue found in one input file, and their text: each issue at its place, one
// per line, `FILE: PLACE: MESSAGE` (just `FILE: MESSAGE` for an issue of the file as a whole). Shared
// by the readers that report every issue at once (designs, printer profiles, calibration data).
#pragma once

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::common {

// The most issues a reader lists for one file. Past it the reader keeps one more saying the list was
// cut, and lists no more: a 20 MB design of ten million bad entries, or a CSV header of twenty
// million unknown columns, took 3 to 5 GB and hundreds of MB of messages when every issue was listed
// (a hostile-input review, 2026-12-05).
inline constexpr std::size_t kMaxListedIssues = 100;
// Adds `issue` to `issues` while fewer than kMaxListedIssues are listed, then one issue of the whole
// file saying the list was cut, then nothing. `Issue` has a `message` and is default-constructible.
template <class Issue>
void listIssue(std::vector<Issue>& issues, Issue issue) {
  if (issues.size() < kMaxListedIssues) {
    issues.push_back(std::move(issue));
  } else if (issues.size() == kMaxListedIssues) {
    Issue cut{};
    cut.message = "more issues follow; only the first " + std::to_string(kMaxListedIssues) + " are listed (fix these and read the file again)";
    issues.push_back(std::move(cut));
  }
}
// True once listIssue has cut the list: a reader may stop reading.
template <class Issue>
bool issueListCut(const std::vector<Issue>& issues) {
  return issues.size() > kMaxListedIssues;
}

// How many issues `issues` lists, the cut line (listIssue's) not counted.
template <class Issue>
std::size_t listedIssueCount(const std::vector<Issue>& issues) {
  return issueListCut(issues) ? kMaxListedIssues : issues.size();
}
// The count a reader's summary line gives: "1 error", "7 errors", or for a cut list "100 errors shown,
// more were found" (the cut line is not an error, and the readers stop counting there).
template <class Issue>
std::string issueCountText(const std::vector<Issue>& issues) {
  const std::size_t listed = listedIssueCount(issues);
  const std::string count = std::to_string(listed) + (listed == 1 ? " error" : " errors");
  return issueListCut(issues) ? count + " shown, more were found" : count;
}

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
