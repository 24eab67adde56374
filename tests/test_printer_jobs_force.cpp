// printer_profiles/ jobs on disk, what --force may replace: only a rodfab job (zip or folder) whose
// every file is the one its manifest records, examined again once anything in it changed; anything
// else is refused and left byte for byte. The job replaced is kept until the command ends. Helpers: tests/printer_jobs_fixture.hpp.
#include "tests/printer_jobs_fixture.hpp"

#include "common/interrupt.hpp"

#include "printer_profiles/zip_writer.hpp"  // internal: the zip writer behind every job

#include <catch2/catch.hpp>
#include <zip.h>

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <fstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

using namespace rodfab::test;

namespace {

// A zip whose entries are (name, text) in this order.
void writeTestZip(const fs::path& file, const std::vector<std::pair<std::string, std::string>>& entries) {
  std::vector<ZipMemoryEntry> zip;
  for (const auto& [name, text] : entries)
    zip.push_back({name, std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size())});
  writeZipFromMemory(file, zip);
}

// A copy of the zip `from` with the entry (name, text) added at its end, by libzip itself.
void copyZipAdding(const fs::path& from, const fs::path& to, const std::string& name, const std::string& text) {
  fs::copy_file(from, to);
  int error = 0;
  zip_t* za = zip_open(to.c_str(), 0, &error);
  REQUIRE(za);
  zip_source_t* source = zip_source_buffer(za, text.data(), text.size(), 0);
  REQUIRE(source);
  REQUIRE(zip_file_add(za, name.c_str(), source, ZIP_FL_ENC_UTF_8) >= 0);
  REQUIRE(zip_close(za) == 0);
}

// A copy of the zip `from` whose last entry holds `text` instead, rewritten by libzip itself; its name.
std::string copyZipReplacingLast(const fs::path& from, const fs::path& to, const std::string& text) {
  fs::copy_file(from, to);
  int error = 0;
  zip_t* za = zip_open(to.c_str(), 0, &error);
  REQUIRE(za);
  const auto last = static_cast<zip_uint64_t>(zip_get_num_entries(za, 0) - 1);
  const std::string name = zip_get_name(za, last, 0);
  zip_source_t* source = zip_source_buffer(za, text.data(), text.size(), 0);
  REQUIRE(source);
  REQUIRE(zip_file_replace(za, last, source, 0) == 0);
  REQUIRE(zip_close(za) == 0);
  return name;
}

// A copy of the zip `from` with a comment on the archive (entry < 0) or on entry `entry`.
void copyZipCommented(const fs::path& from, const fs::path& to, int entry, const std::string& text) {
  fs::copy_file(from, to);
  int error = 0;
  zip_t* za = zip_open(to.c_str(), 0, &error);
  REQUIRE(za);
  if (entry < 0) REQUIRE(zip_set_archive_comment(za, text.data(), static_cast<zip_uint16_t>(text.size())) == 0);
  else REQUIRE(zip_file_set_comment(za, static_cast<zip_uint64_t>(entry), text.data(), static_cast<zip_uint16_t>(text.size()), 0) == 0);
  REQUIRE(zip_close(za) == 0);
}

void appendText(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::app | std::ios::binary);
  out << text;
  REQUIRE(out.good());
}

// The first BMP layer image of a folder job (by name).
fs::path firstLayerImage(const fs::path& job) {
  std::vector<fs::path> images;
  for (const auto& entry : fs::directory_iterator(job))
    if (entry.path().extension() == ".bmp") images.push_back(entry.path());
  REQUIRE(!images.empty());
  return *std::min_element(images.begin(), images.end());
}

// Inverts the byte after a BMP's 62-byte header (its first row's first pixels): same length, new bytes.
void flipFirstByteAfterHeader(const fs::path& file) {
  std::fstream io(file, std::ios::in | std::ios::out | std::ios::binary);
  io.seekg(62);
  char byte = 0;
  REQUIRE(io.get(byte));
  io.seekp(62);
  io.put(static_cast<char>(~byte));
  REQUIRE(io.good());
}

// The job of `grid` written as a zip at `zip` and as a folder at `folder`.
void writeZipAndFolderJobs(const openvdb::BoolGrid& grid, const fs::path& zip, const fs::path& folder) {
  writeJob(grid, specFor(grid, zip), 24);
  JobSpec spec = specFor(grid, folder);
  spec.options.archive = ArchiveFormat::Directory;
  writeJob(grid, spec, 24);
}

}  // namespace

TEST_CASE("Force replaces only rodfab jobs: anything else is refused and left byte for byte", "[job][force]") {
  const fs::path dir = scratch("force-refusals");
  const auto grid = overhangPart(21);
  writeZipAndFolderJobs(*grid, dir / "real.zip", dir / "real-dir");
  // A user's folder, an empty one, a file, foreign zips, a link to a job, a job folder with a file added.
  fs::create_directories(dir / "mydata" / "sub");
  writeAll(dir / "mydata" / "notes.txt", Bytes{'h', 'i'});
  writeAll(dir / "mydata" / "sub" / "manifest.json", Bytes{'{', '}'});
  fs::create_directories(dir / "empty");
  writeAll(dir / "thesis.zip", Bytes{'n', 'o', 't', ' ', 'a', ' ', 'z', 'i', 'p'});
  writeTestZip(dir / "photos.zip", {{"IMG_0001.jpg", "jpeg"}, {"manifest.json", std::string("{\"format\": \"") + kJobFormat + "\"}"}});
  writeTestZip(dir / "other-tool.zip", {{"manifest.json", "{\"format\": \"other.job/1\", \"files\": {}}"}});
  writeTestZip(dir / "deep.zip", {{"manifest.json", std::string(100000, '[') + std::string(100000, ']')}});
  fs::create_symlink(dir / "real.zip", dir / "link.zip");
  fs::create_symlink(dir / "mydata", dir / "link-dir");
  copyZipAdding(dir / "real.zip", dir / "zip-plus.zip", "thesis.txt", "years of work");
  writeTestZip(dir / "bare-manifest.zip", {{"manifest.json", std::string("{\"format\": \"") + kJobFormat + "\"}"}, {"important.docx", "mine"}});
  fs::copy(dir / "real-dir", dir / "job-plus", fs::copy_options::recursive);
  writeAll(dir / "job-plus" / "my-notes.txt", Bytes{'!'});
  fs::copy(dir / "real-dir", dir / "job-plus-preview", fs::copy_options::recursive);
  writeAll(dir / "job-plus-preview" / "previews" / "mine.png", Bytes{'!'});
  // Jobs in which a person changed a file: notes added to a layer image's end, one byte of one changed
  // (the same length), an entry of the zip rewritten by libzip, a hand-made manifest listing a file
  // without its checksum.
  fs::copy(dir / "real-dir", dir / "job-noted", fs::copy_options::recursive);
  appendText(firstLayerImage(dir / "job-noted"), "nozzle 3 clogged here");
  fs::copy(dir / "real-dir", dir / "job-touched", fs::copy_options::recursive);
  flipFirstByteAfterHeader(firstLayerImage(dir / "job-touched"));
  const std::string rewritten = copyZipReplacingLast(dir / "real.zip", dir / "zip-noted.zip", "my notes");
  writeTestZip(dir / "listed-manifest.zip", {{"manifest.json", std::string("{\"format\": \"") + kJobFormat + "\", \"files\": {\"thesis.txt\": {}}}"},
                                             {"thesis.txt", "the only copy"}});
  // Notes written into the zip itself (zip -z, zip -c): replacing the job would lose them.
  copyZipCommented(dir / "real.zip", dir / "zip-commented.zip", -1, "printed on tray 2; nozzle 3 clogged");
  copyZipCommented(dir / "real.zip", dir / "entry-commented.zip", 1, "this layer curled");
  REQUIRE(::mkfifo((dir / "pipe").c_str(), 0600) == 0);
  const auto before = snapshot(dir);

  const std::vector<std::pair<std::string, std::string>> cases = {
      {"mydata", "a folder without a rodfab job manifest"},
      {"mydata/", "a folder without a rodfab job manifest"},
      {"empty", "a folder without a rodfab job manifest"},
      {"thesis.zip", "a file that is not a zip archive"},
      {"photos.zip", "whose first entry is not a rodfab job manifest"},
      {"other-tool.zip", "is not a rodfab job manifest"},
      {"deep.zip", "is not a rodfab job manifest"},
      {"link.zip", "a symbolic link"},
      {"link-dir", "a symbolic link"},
      {"zip-plus.zip", "'thesis.txt', which is not part of that job"},
      {"bare-manifest.zip", "'important.docx', which is not part of that job"},
      {"job-plus", "'my-notes.txt', which is not part of that job"},
      {"job-plus-preview", "'previews/mine.png', which is not part of that job"},
      {"pipe", "a named pipe"},
      {"job-noted", "'" + firstLayerImage(dir / "job-noted").filename().string() + "' was changed since rodfab wrote it"},
      {"job-touched", "'" + firstLayerImage(dir / "job-touched").filename().string() + "' was changed since rodfab wrote it"},
      {"zip-noted.zip", "'" + rewritten + "' was changed since rodfab wrote it"},
      {"listed-manifest.zip", "'thesis.txt' was changed since rodfab wrote it"},
      {"zip-commented.zip", "a rodfab job with a comment added to the archive"},
      {"entry-commented.zip", "a rodfab job with a comment added to its entry"},
  };
  for (const auto& [name, what] : cases)
    for (const bool force : {true, false}) {
      INFO(name << (force ? " with force" : " without force"));
      JobSpec spec = specFor(*grid, dir.string() + "/" + name);
      spec.options.force = force;
      CHECK_THROWS_WITH(writeJob(*grid, spec, 24), Catch::Contains(what) && Catch::Contains("rodfab replaces only its own jobs"));
    }
  CHECK((snapshot(dir) == before));  // every refused path intact, and no temporaries anywhere
  // Names reserved for staging folders (a later job would remove such a job as a dead writer's).
  CHECK_THROWS_WITH(JobWriter(specFor(*grid, dir / ".job.zip.rodfab-partial-1-0")), Catch::Contains("named like rodfab's hidden staging"));
  CHECK_THROWS_WITH(JobWriter(specFor(*grid, dir / ".")), Catch::Contains("give the job a name of its own"));
  CHECK((snapshot(dir) == before));
}

TEST_CASE("A job examined once is read again once anything in it changed", "[job][force]") {
  // examineOutput remembers a job it read whole by the status of its entries (the writer examines the
  // output up to three times a run): a change after the first look must still be seen.
  const fs::path dir = scratch("force-reexamine");
  const auto grid = overhangPart(24);
  writeZipAndFolderJobs(*grid, dir / "job.zip", dir / "job");
  // Only a job whose last change is some seconds old is remembered (a file changed twice within one
  // tick of the file system's clock would keep its times), so that one is tested.
  std::this_thread::sleep_for(std::chrono::milliseconds(3100));
  REQUIRE(examineOutput(dir / "job.zip").kind == OutputOccupant::Kind::RodfabJob);
  REQUIRE(examineOutput(dir / "job").kind == OutputOccupant::Kind::RodfabJob);
  fs::rename(dir / "job.zip", dir / "old.zip");
  const std::string rewritten = copyZipReplacingLast(dir / "old.zip", dir / "job.zip", "my notes");
  flipFirstByteAfterHeader(firstLayerImage(dir / "job"));
  std::this_thread::sleep_for(std::chrono::milliseconds(3100));  // the change settled: found by its stamp
  const OutputOccupant zip = examineOutput(dir / "job.zip"), changed = examineOutput(dir / "job");
  CHECK(zip.kind == OutputOccupant::Kind::Other);
  CHECK_THAT(zip.description, Catch::Contains("'" + rewritten + "' was changed since rodfab wrote it"));
  CHECK(changed.kind == OutputOccupant::Kind::Other);
  CHECK_THAT(changed.description, Catch::Contains("was changed since rodfab wrote it"));
  CHECK(examineOutput(dir / "old.zip").kind == OutputOccupant::Kind::RodfabJob);
}

TEST_CASE("Force replaces a rodfab job, zip or folder, by one of either kind", "[job][force]") {
  const fs::path dir = scratch("force-replace");
  const auto first = overhangPart(22), second = overhangPart(23);
  for (const ArchiveFormat oldFormat : {ArchiveFormat::Zip, ArchiveFormat::Directory})
    for (const ArchiveFormat newFormat : {ArchiveFormat::Zip, ArchiveFormat::Directory}) {
      INFO(toString(oldFormat) << " replaced by " << toString(newFormat));
      fs::remove_all(dir / "job");
      JobSpec old = specFor(*first, dir / "job");
      old.options.archive = oldFormat;
      writeJob(*first, old, 24);
      JobSpec spec = specFor(*second, dir / "job");
      spec.options.archive = newFormat;
      CHECK_THROWS_WITH(writeJob(*second, spec, 24), Catch::Contains("already exists there; use --force"));
      spec.options.force = true;
      writeJob(*second, spec, 24);
      CHECK(fs::is_directory(dir / "job") == (newFormat == ArchiveFormat::Directory));
      CHECK((decodeJob(dir / "job") == gridVoxels(*second)));
      CHECK(inspectJob(dir / "job").ok());
      CHECK(std::distance(fs::directory_iterator(dir), fs::directory_iterator()) == 1);  // no old job, no temporaries
    }
}

namespace {

enum class Ending { Success, Failure, LateSignal, StopAfterCommit };

// Runs `body` in a child process and returns its exit code (-1 when it died of a signal). The job
// writer and the signal handlers run in the child only: a signal raised there, and its watchdog,
// cannot touch this process, and the child forks before this process has started any TBB worker.
template <class Body>
int inChild(Body&& body) {
  const pid_t child = ::fork();
  REQUIRE(child >= 0);
  if (child == 0) {
    int code = 98;
    try {
      code = body();
    } catch (...) {
      code = 97;
    }
    ::_exit(code);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

bool holdsKeptCopy(const fs::path& dir) {
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().starts_with(".job.rodfab-old-")) return true;
  return false;
}

// A command that replaces the job at dir/job under --force and ends as `ending` says, as rodfab's
// main ends it (common::finishCommand with the owner of its outputs); its exit code, or 90 when the
// replaced job was not kept beside the new one while the command ran.
int forceCommand(const fs::path& dir, ArchiveFormat format, Ending ending) {
  rodfab::common::installInterruptHandlers();
  rodfab::common::CommandOutputs outputs;
  const auto second = overhangPart(29);
  JobSpec spec = specFor(*second, dir / "job");
  spec.options.archive = format;
  spec.options.force = true;
  struct Stop {};
  int calls = 0, checks = format == ArchiveFormat::Zip ? 4 : 3;
  if (ending == Ending::StopAfterCommit) spec.options.checkInterrupt = [&] {
      if (++calls == checks) throw Stop{};  // the check right after the commit
    };
  try {
    writeJob(*second, spec, 24);
  } catch (const Stop&) {
    return rodfab::common::finishCommand(outputs, 130);
  }
  if (!holdsKeptCopy(dir)) return 90;
  if (ending == Ending::LateSignal) ::raise(SIGINT);  // after the writer returned, before the command did
  return rodfab::common::finishCommand(outputs, ending == Ending::Failure ? 1 : 0);
}

}  // namespace

TEST_CASE("A job replaced under force is kept until the command ends: back byte for byte when it fails or is interrupted",
          "[job][force][interrupt]") {
  const fs::path dir = scratch("force-kept");
  for (const ArchiveFormat oldFormat : {ArchiveFormat::Zip, ArchiveFormat::Directory})
    for (const ArchiveFormat newFormat : {ArchiveFormat::Zip, ArchiveFormat::Directory})
      for (const Ending ending : {Ending::LateSignal, Ending::Failure, Ending::StopAfterCommit, Ending::Success}) {
        INFO(toString(oldFormat) << " replaced by " << toString(newFormat) << ", ending " << static_cast<int>(ending));
        fs::remove_all(dir);
        fs::create_directories(dir);
        REQUIRE(inChild([&] {
                  const auto first = overhangPart(28);
                  JobSpec old = specFor(*first, dir / "job");
                  old.options.archive = oldFormat;
                  writeJob(*first, old, 24);
                  return 0;
                }) == 0);
        const auto before = snapshot(dir);
        const int code = inChild([&] { return forceCommand(dir, newFormat, ending); });
        if (ending == Ending::Success) {
          CHECK(code == 0);
          CHECK(snapshot(dir) != before);
          CHECK(std::distance(fs::directory_iterator(dir), fs::directory_iterator()) == 1);  // the new job; nothing kept
          CHECK(fs::is_directory(dir / "job") == (newFormat == ArchiveFormat::Directory));
        } else {
          CHECK(code == (ending == Ending::Failure ? 1 : 130));
          CHECK((snapshot(dir) == before));  // the old job, byte for byte, and nothing else
        }
      }
}
