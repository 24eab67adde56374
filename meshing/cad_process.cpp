// rodsFromCad: the reading runs in a child process, the helper rodfab-cad-reader (cad_reader.hpp says
// why). This side starts it, waits for its answer while honouring SIGINT / SIGTERM, and turns whatever
// became of it (an answer, an error, a crash, a lie) into CadRods or a MeshError naming the file.
#include "common/interrupt.hpp"
#include "common/memory_budget.hpp"
#include "geometry/design_file.hpp"
#include "geometry/design_writer.hpp"
#include "meshing/cad_reader.hpp"
#include "meshing/input_file.hpp"

#include <dlfcn.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <limits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>

extern char** environ;

namespace rodfab::meshing {

namespace {

// Where this library was loaded from: the helper lies beside it, in the build tree and when installed.
const char kAnchor = 0;

std::filesystem::path helperBesideThisLibrary() {
  Dl_info self{};
  if (::dladdr(&kAnchor, &self) == 0 || self.dli_fname == nullptr) return RODFAB_CAD_READER;
  return std::filesystem::path(self.dli_fname).parent_path() / RODFAB_CAD_READER;
}

std::string hexDouble(double value) {
  char text[64];
  std::snprintf(text, sizeof text, "%a", value);
  return text;
}

double parseDouble(const std::string& text) {
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0') throw std::invalid_argument("not a number: '" + text + "'");
  return value;
}

// A pipe whose ends are closed in every child but the one they are handed to.
struct Pipe {
  int read = -1, write = -1;
  Pipe() {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) throw std::runtime_error(std::string("cannot make a pipe: ") + std::strerror(errno));
    read = fds[0], write = fds[1];
  }
  ~Pipe() {
    closeRead();
    closeWrite();
  }
  void closeRead() {
    if (read >= 0) ::close(read), read = -1;
  }
  void closeWrite() {
    if (write >= 0) ::close(write), write = -1;
  }
};

// The helper's process: killed and reaped if it is still running when this goes out of scope.
class Child {
public:
  Child(const std::filesystem::path& helper, const std::vector<std::string>& arguments, Pipe& result, Pipe& messages) {
    std::vector<std::string> argv{helper.string()};
    argv.insert(argv.end(), arguments.begin(), arguments.end());
    std::vector<char*> pointers;
    for (std::string& a : argv) pointers.push_back(a.data());
    pointers.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_adddup2(&actions, messages.write, 2);
    posix_spawn_file_actions_adddup2(&actions, result.write, detail::kResultDescriptor);
    // No signal blocked, and SIGINT, SIGTERM and SIGPIPE at their defaults, whatever the calling
    // thread has: a Ctrl-C ends the reader with rodfab.
    posix_spawnattr_t attributes;
    posix_spawnattr_init(&attributes);
    sigset_t none, defaults;
    sigemptyset(&none);
    sigemptyset(&defaults);
    for (int signal : {SIGINT, SIGTERM, SIGPIPE}) sigaddset(&defaults, signal);
    posix_spawnattr_setsigmask(&attributes, &none);
    posix_spawnattr_setsigdefault(&attributes, &defaults);
    posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
    const int error = ::posix_spawn(&pid_, argv[0].c_str(), &actions, &attributes, pointers.data(), environ);
    posix_spawnattr_destroy(&attributes);
    posix_spawn_file_actions_destroy(&actions);
    if (error != 0) pid_ = -1, spawnError_ = error;
    result.closeWrite();
    messages.closeWrite();
  }
  ~Child() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      reap();
    }
  }
  int spawnError() const { return spawnError_; }
  void kill() {
    if (pid_ > 0) ::kill(pid_, SIGKILL);  // never kill(-1): that would signal every process we may
  }
  // The wait status once the child has ended.
  int reap() {
    int status = 0;
    while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
    return status;
  }

private:
  pid_t pid_ = -1;
  int spawnError_ = 0;
};

// Reads both pipes to their ends, polling for SIGINT / SIGTERM every 0.1 s (the child is killed
// then). The helper's messages are kept to their last 4 kB; the answer to 1/48 of the memory budget:
// parsing it takes ~24 bytes a byte of text, once as a document and once more in parseDesign.
void readAnswer(Child& child, Pipe& result, Pipe& messages, std::string& answer, std::string& stderrTail,
                const std::filesystem::path& file) {
  const std::uint64_t limit = common::memoryBudget() / 48;
  char buffer[65536];
  while (result.read >= 0 || messages.read >= 0) {
    pollfd fds[2] = {{result.read, POLLIN, 0}, {messages.read, POLLIN, 0}};
    if (::poll(fds, 2, 100) < 0 && errno != EINTR) throw MeshError(file, std::string("waiting for the CAD reader: ") + std::strerror(errno));
    if (common::interruptRequested()) {
      child.kill();
      common::throwIfInterrupted();
    }
    for (int i = 0; i < 2; ++i) {
      if (fds[i].fd < 0 || !(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      const ssize_t n = ::read(fds[i].fd, buffer, sizeof buffer);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        (i == 0 ? result : messages).closeRead();
        continue;
      }
      std::string& into = i == 0 ? answer : stderrTail;
      into.append(buffer, static_cast<std::size_t>(n));
      if (i == 1 && stderrTail.size() > 4096) stderrTail.erase(0, stderrTail.size() - 4096);
      if (i == 0 && answer.size() > limit) {
        child.kill();
        throw MeshError(file, "the CAD reader's design is larger than the memory budget can parse (" +
                                  std::to_string(limit >> 20) + " MiB of text at --max-memory " +
                                  std::to_string(common::memoryBudget() >> 20) + " MiB); split the model");
      }
    }
  }
}

std::string describeEnd(int status, const std::string& stderrTail) {
  std::string what;
  if (WIFSIGNALED(status)) {
    const int signal = WTERMSIG(status);
    const char* name = ::sigdescr_np(signal);  // thread-safe, unlike strsignal
    const std::string which = "(signal " + std::to_string(signal) + ", " + (name ? name : "?") + ")";
    what = signal == SIGKILL ? "the CAD reader was killed " + which + ", not by rodfab: the system may have run out of "
                                   "memory (lower --max-memory, or free memory)"
                             : "the CAD reader (OpenCASCADE) crashed on this file " + which + ": the file is malformed in a "
                                   "way rodfab's checks do not recognise; re-export it, or check it in the program that wrote it";
  } else {
    what = "the CAD reader stopped with exit code " + std::to_string(WEXITSTATUS(status)) + " and no answer";
  }
  std::string tail = stderrTail;
  while (!tail.empty() && (tail.back() == '\n' || tail.back() == ' ')) tail.pop_back();
  if (!tail.empty()) what += " (it said: " + tail.substr(tail.size() > 300 ? tail.size() - 300 : 0) + ")";
  return what;
}

// The reader's answer, its design not yet checked.
struct ReaderAnswer {
  nlohmann::ordered_json design;  // ordered: a design written from it keeps the format's key order
  CadRodReport report;
};

ReaderAnswer parseAnswer(const std::string& answer, const std::filesystem::path& file) {
  nlohmann::ordered_json doc = nlohmann::ordered_json::parse(answer, nullptr, false);
  if (doc.is_discarded() || !doc.is_object()) throw MeshError(file, "the CAD reader's answer is not JSON");
  if (doc.contains("error") && doc["error"].is_string()) throw MeshError(file, doc["error"].get<std::string>());
  if (!doc.contains("design") || !doc.contains("report") || !doc["report"].is_object())
    throw MeshError(file, "the CAD reader's answer has no design and report");
  ReaderAnswer out;
  try {
    const nlohmann::ordered_json& r = doc["report"];
    out.report.edges = r.at("edges").get<std::size_t>();
    out.report.rods = r.at("rods").get<std::size_t>();
    out.report.joints = r.at("joints").get<std::size_t>();
    out.report.skippedDegenerate = r.at("skipped_degenerate").get<std::size_t>();
    out.report.largestEndMove = r.at("largest_end_move_mm").get<double>();
    out.report.approximated = r.at("approximated").get<std::size_t>();
    out.report.largestApproximationError = r.at("largest_approximation_error_mm").get<double>();
    out.report.untranslated = r.at("untranslated").get<std::size_t>();
    out.report.firstUntranslated = r.at("first_untranslated").get<std::string>();
    const nlohmann::ordered_json& radius = r.at("smallest_bend_radius_mm");  // null: every rod straight
    out.report.smallestBendRadius = radius.is_null() ? std::numeric_limits<double>::infinity() : radius.get<double>();
    out.report.rodsBentTighterThanSection = r.at("rods_bent_tighter_than_section").get<std::size_t>();
  } catch (const nlohmann::json::exception& e) {
    throw MeshError(file, std::string("the CAD reader's report is malformed: ") + e.what());
  }
  out.design = std::move(doc["design"]);
  return out;
}

// check(text, sourceName) on the answer's design, as `rodfab validate` reads designs (the parent
// trusts nothing the process running OpenCASCADE on a hostile file says); returns what it returns,
// its errors as MeshErrors.
template <class Check>
auto checkedDesign(const ReaderAnswer& answer, const std::filesystem::path& file, Check check) {
  try {
    return check(answer.design.dump(), file.string());
  } catch (const geometry::DesignError& e) {
    throw MeshError(file, std::string("the CAD reader's design is not valid: ") + e.what());
  } catch (const std::bad_alloc&) {  // the rods' samples: ~0.1-1 MB a winding rod
    throw MeshError(file, "building the model's rods ran out of memory (the memory budget, --max-memory, is " +
                              std::to_string(common::memoryBudget() >> 20) + " MiB): raise --max-memory, or split the model");
  }
}

// The reader's report counts the rods its design holds; a process that says otherwise is not trusted.
void requireReportMatches(const CadRodReport& report, std::size_t rodsInDesign, const std::filesystem::path& file) {
  if (report.rods != rodsInDesign) throw MeshError(file, "the CAD reader's report does not match its design");
}

}  // namespace

namespace detail {

std::vector<std::string> readerArguments(const CadReaderRequest& r) {
  const geometry::Section& s = r.options.section;
  return {r.file.string(), std::string(geometry::toString(s.shape)), hexDouble(s.width), hexDouble(s.height), r.options.caps == geometry::CapStyle::Round ? "round" : "flat",
          hexDouble(r.options.modulusMpa), hexDouble(r.options.jointTolerance), std::to_string(r.memoryBudget),
          std::to_string(r.parentProcess)};
}

CadReaderRequest fromReaderArguments(const std::vector<std::string>& a) {
  if (a.size() != 9) throw std::invalid_argument("expected 9 arguments, got " + std::to_string(a.size()));
  CadReaderRequest r;
  r.file = a[0];
  const double width = parseDouble(a[2]), height = parseDouble(a[3]);
  if (a[1] == "circle") r.options.section = geometry::Section::circle(width);
  else if (a[1] == "ellipse") r.options.section = geometry::Section::ellipse(width, height);
  else if (a[1] == "rectangle") r.options.section = geometry::Section::rectangle(width, height);
  else throw std::invalid_argument("unknown section '" + a[1] + "'");
  if (a[4] != "round" && a[4] != "flat") throw std::invalid_argument("unknown caps '" + a[4] + "'");
  r.options.caps = a[4] == "round" ? geometry::CapStyle::Round : geometry::CapStyle::Flat;
  r.options.modulusMpa = parseDouble(a[5]);
  r.options.jointTolerance = parseDouble(a[6]);
  r.memoryBudget = std::stoull(a[7]);
  r.parentProcess = std::stol(a[8]);
  return r;
}

std::string resultJson(CadDesign design) {
  const CadRodReport& r = design.report;
  nlohmann::ordered_json answer;
  answer["design"] = std::move(design.design);  // moved, not copied: it is most of the helper's memory
  answer["report"] = {{"edges", r.edges}, {"rods", r.rods}, {"joints", r.joints}, {"skipped_degenerate", r.skippedDegenerate},
                      {"largest_end_move_mm", r.largestEndMove}, {"approximated", r.approximated},
                      {"largest_approximation_error_mm", r.largestApproximationError}, {"untranslated", r.untranslated},
                      {"first_untranslated", r.firstUntranslated},
                      {"smallest_bend_radius_mm", std::isfinite(r.smallestBendRadius) ? nlohmann::ordered_json(r.smallestBendRadius)
                                                                                       : nlohmann::ordered_json()},
                      {"rods_bent_tighter_than_section", r.rodsBentTighterThanSection}};
  return answer.dump();
}

std::string errorJson(const std::string& message) { return nlohmann::json{{"error", message}}.dump(); }

void checkCadFile(const std::filesystem::path& file, geometry::RodsKept kept) {
  // The least memory a byte of CAD text was measured to need (peak RSS less the process's at rest,
  // STEP curve sets of straight lines and of winding B-splines, meshing/README.md): rodfab keeping the
  // rods, 67-70 bytes a byte for lines, 274-276 for the splines (their samples); rodfab writing the
  // design without them, 17 and 8.6; the reader itself 10-23. A file refused here would need more than
  // the budget at the least rate measured; one let through may still run out, and the message says so
  // (each process's data limit is the budget).
  const std::uint64_t bytesPerFileByte = kept == geometry::RodsKept::All ? 64 : 8;
  detail::requireExtension(file, "CAD", {".step", ".stp", ".iges", ".igs"});
  const std::uintmax_t size = detail::checkedFileSize(file, "");
  common::requireMemory(std::uint64_t(size) * bytesPerFileByte,
                        {.what = "reading the CAD model " + file.string(), .remedy = "split the model"});
}

namespace {

// The reader's answer for `cadFile`: run at `helper`, waited for (SIGINT / SIGTERM honoured), its end
// turned into a MeshError unless it answered.
ReaderAnswer readerAnswer(const std::filesystem::path& helper, const std::filesystem::path& cadFile, const CadRodOptions& options,
                          geometry::RodsKept kept) {
  if (!(options.jointTolerance > 0) || !(options.modulusMpa > 0)) throw std::invalid_argument("rodsFromCad: options out of range");
  checkCadFile(cadFile, kept);
  Pipe result, messages;
  Child child(helper, readerArguments({cadFile, options, common::memoryBudget(), static_cast<long>(::getpid())}), result, messages);
  if (child.spawnError())
    throw MeshError(cadFile, "cannot read CAD files: the CAD reader " + helper.string() + " did not start (" +
                                 std::strerror(child.spawnError()) + "); rodfab's installation is incomplete");
  std::string answer, stderrTail;
  readAnswer(child, result, messages, answer, stderrTail, cadFile);
  const int status = child.reap();
  if (common::interruptRequested()) common::throwIfInterrupted();
  // An error answered before a non-zero exit is still the reader's own message.
  if (!(WIFEXITED(status) && (WEXITSTATUS(status) == 0 || !answer.empty()))) throw MeshError(cadFile, describeEnd(status, stderrTail));
  return parseAnswer(answer, cadFile);
}

}  // namespace

CadRods rodsFromCadThrough(const std::filesystem::path& helper, const std::filesystem::path& cadFile,
                           const CadRodOptions& options) {
  const ReaderAnswer answer = readerAnswer(helper, cadFile, options, geometry::RodsKept::All);
  CadRods out{checkedDesign(answer, cadFile, geometry::parseDesign), answer.report};
  requireReportMatches(answer.report, out.structure.rods.size(), cadFile);
  out.structure.source = cadFile.string();
  return out;
}

CadDesignWritten writeDesignFromCadThrough(const std::filesystem::path& helper, const std::filesystem::path& cadFile,
                                           const CadRodOptions& options, const std::filesystem::path& designFile,
                                           const std::string& description) {
  ReaderAnswer answer = readerAnswer(helper, cadFile, options, geometry::RodsKept::SummaryOnly);
  const geometry::DesignSummary summary = checkedDesign(answer, cadFile, geometry::summarizeDesign);
  requireReportMatches(answer.report, summary.rodCount, cadFile);
  geometry::writeDesignDocument(geometry::designJson(std::move(answer.design["rods"]), description), designFile);
  return {answer.report, summary};
}

}  // namespace detail

CadRods rodsFromCad(const std::filesystem::path& cadFile, const CadRodOptions& options) {
  return detail::rodsFromCadThrough(helperBesideThisLibrary(), cadFile, options);
}

CadDesignWritten writeDesignFromCad(const std::filesystem::path& cadFile, const CadRodOptions& options,
                                    const std::filesystem::path& designFile, const std::string& description) {
  return detail::writeDesignFromCadThrough(helperBesideThisLibrary(), cadFile, options, designFile, description);
}

}  // namespace rodfab::meshing
