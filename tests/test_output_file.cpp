// common/output_file.hpp: output paths checked before any work (a name too long for the hidden
// temporary beside it), and the files a commit replaces kept until the command ends.
#include "common/interrupt.hpp"
#include "common/output_file.hpp"
#include "tests/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace rodfab::common;

namespace {

std::string readAll(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string thrownBy(const auto& call) {
  try {
    call();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("an output name too long for the hidden temporary beside it is refused up front, naming the path and the limits") {
  const rodfab::test::TempDir dir("output-file");
  const OutputPolicy policy{"test file", false, "--force", {}};
  // 255 bytes per name on this file system (ext4, tmpfs): 220 leaves room for the 35 bytes rodfab adds.
  const fs::path longest = dir.path / (std::string(215, 'k') + ".json");
  const fs::path tooLong = dir.path / (std::string(216, 'k') + ".json");
  const fs::path farTooLong = dir.path / (std::string(250, 'n') + ".out");
  REQUIRE_NOTHROW(checkOutputPath(longest, {}, policy));
  writeFileAtomically(longest, "fits");  // its temporary's name fits too
  CHECK(readAll(longest) == "fits");
  CHECK(thrownBy([&] { checkOutputPath(tooLong, {}, policy); }) ==
        tooLong.string() + ": the file name is 221 bytes long; rodfab writes it first under a hidden name up to 35 bytes longer, "
                           "and this folder's file system allows names of at most 255 bytes: use a name of at most 220 bytes");
  CHECK(thrownBy([&] { checkOutputNameLength(farTooLong); }).starts_with(farTooLong.string() + ": the file name is 254 bytes long;"));
  // A path whose hidden sibling would pass PATH_MAX (4096): refused too (the name itself is short).
  fs::path deep = dir.path;
  while (deep.string().size() < 4096 - 40) deep /= std::string(100, 'd');
  CHECK(thrownBy([&] { checkOutputNameLength(deep / "x.json"); }).find(": the path is ") != std::string::npos);
  CHECK_FALSE(fs::exists(tooLong));
  CHECK_FALSE(fs::exists(farTooLong));
}

namespace {

// The names in `dir`, sorted.
std::vector<std::string> namesIn(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

}  // namespace

TEST_CASE("without an owner of the command's outputs, a commit replaces outright and leaves nothing beside the output") {
  const rodfab::test::TempDir dir("output-owner");
  const fs::path file = dir.path / "cal.json";
  writeFileAtomically(file, "old");
  writeFileAtomically(file, "new");  // a library user: no CommandOutputs, no finishCommand
  CHECK(readAll(file) == "new");
  CHECK(namesIn(dir.path) == std::vector<std::string>{"cal.json"});  // no .cal.json.rodfab-old-PID-N
}

TEST_CASE("the owner of the command's outputs keeps what a commit replaced until it ends - gone on success, back on failure") {
  const rodfab::test::TempDir dir("output-owner");
  const fs::path file = dir.path / "cal.json", other = dir.path / "plot.png";
  writeFileAtomically(file, "old");
  const auto keptName = [&] {
    const std::vector<std::string> names = namesIn(dir.path);
    for (const std::string& n : names)
      if (n.starts_with(".cal.json.rodfab-old-")) return n;
    return std::string();
  };

  SECTION("success: the output stays, the kept copy goes") {
    CommandOutputs outputs;
    writeFileAtomically(file, "new");
    writeFileAtomically(other, "plot");
    REQUIRE_FALSE(keptName().empty());  // kept while the command runs
    CHECK(readAll(dir.path / keptName()) == "old");
    CHECK(outputs.finish(0) == 0);
    CHECK(readAll(file) == "new");
    CHECK(namesIn(dir.path) == std::vector<std::string>{"cal.json", "plot.png"});
    CHECK(outputs.finish(1) == 1);  // only the first call acts: nothing is taken back now
    CHECK(readAll(file) == "new");
  }
  SECTION("failure: every output committed is taken back, the replaced file is back byte for byte") {
    CommandOutputs outputs;
    writeFileAtomically(file, "new");
    writeFileAtomically(other, "plot");
    CHECK(outputs.finish(1) == 1);
    CHECK(readAll(file) == "old");
    CHECK(namesIn(dir.path) == std::vector<std::string>{"cal.json"});
  }
  SECTION("the owner ends without finish (an exception passed through it) - a failure") {
    try {
      CommandOutputs outputs;
      writeFileAtomically(file, "new");
      throw std::runtime_error("a later step failed");
    } catch (const std::runtime_error&) {
    }
    CHECK(readAll(file) == "old");
    CHECK(namesIn(dir.path) == std::vector<std::string>{"cal.json"});
  }
  SECTION("one owner at a time") {
    CommandOutputs outputs;
    CHECK_THROWS_AS(CommandOutputs(), std::logic_error);
    CHECK(outputs.finish(0) == 0);
    CommandOutputs next;  // the next command's
    CHECK(next.finish(0) == 0);
  }
}

namespace {

// A pid that ran and has ended (its child was reaped): no process has it unless the system reuses it.
long endedProcessId() {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  int status = 0;
  ::waitpid(child, &status, 0);
  return child;
}

void writeText(const fs::path& file, const std::string& text) { std::ofstream(file, std::ios::binary) << text; }

}  // namespace

TEST_CASE("copies a killed run kept beside an output are reported, never removed, unless they are the output itself") {
  const rodfab::test::TempDir dir("output-file");
  const fs::path output = dir.path / "design.json";
  writeText(output, "the new design");
  const std::string dead = std::to_string(endedProcessId()), alive = std::to_string(::getpid());
  const fs::path earlier = dir.path / (".design.json.rodfab-old-" + dead + "-0");  // the version a killed run replaced
  const fs::path link = dir.path / (".design.json.rodfab-old-" + dead + "-1");     // killed before its commit's rename
  const fs::path ownRun = dir.path / (".design.json.rodfab-old-" + alive + "-0");  // this process's own: still in use
  const fs::path otherName = dir.path / (".other.json.rodfab-old-" + dead + "-0");
  const fs::path notOurs = dir.path / (".design.json.rodfab-old-" + dead + "-0.bak");
  writeText(earlier, "the design before");
  fs::create_hard_link(output, link);
  for (const fs::path& f : {ownRun, otherName, notOurs}) writeText(f, "x");
  CHECK(leftoverPreviousVersions(output) == std::vector<fs::path>{earlier});
  CHECK(readAll(earlier) == "the design before");
  CHECK_FALSE(fs::exists(link));
  CHECK(readAll(output) == "the new design");
  for (const fs::path& f : {ownRun, otherName, notOurs}) CHECK(fs::exists(f));
  // A job folder, given with a trailing slash, and its kept folder.
  const fs::path job = dir.path / "job", keptJob = dir.path / (".job.rodfab-old-" + dead + "-3");
  fs::create_directories(job);
  fs::create_directories(keptJob / "layers");
  CHECK(leftoverPreviousVersions(dir.path / "job/") == std::vector<fs::path>{keptJob});
  CHECK(fs::exists(keptJob / "layers"));
}

TEST_CASE("what is written is flushed to the device before a name points at it, and a failure is said") {
  const fs::path dir = fs::temp_directory_path() / ("rodfab-sync-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "job");
  writeFileAtomically(dir / "a.json", "{}");
  CHECK_NOTHROW(syncToDevice(dir / "a.json"));
  CHECK_NOTHROW(syncToDevice(dir / "job"));  // a folder job: its file system in one flush
  CHECK(syncFolderEntries(dir));
  CHECK_THROWS_WITH(syncToDevice(dir / "gone.zip"), Catch::Contains("gone.zip: cannot flush it to disk"));
  CHECK_FALSE(syncFolderEntries(dir / "gone"));
  // Starting the writeback early is a hint: on a file it leaves the bytes as they were, and a file
  // that is gone or a folder changes nothing and throws nothing.
  startWriteback(dir / "a.json");
  CHECK(readAll(dir / "a.json") == "{}");
  startWriteback(dir / "gone.zip");
  startWriteback(dir / "job");
  CHECK_FALSE(fs::exists(dir / "gone.zip"));
  fs::remove_all(dir);
}
