// printer_profiles/ jobs on disk: a job replaces only a rodfab job and only with force, a failed or
// interrupted write leaves nothing that looks like a job and the target as it was, withdrawJob and the
// removal of dead writers' staging folders touch nothing else. Helpers: tests/printer_jobs_fixture.hpp.
#include "tests/printer_jobs_fixture.hpp"

#include "printer_profiles/job_reader.hpp"  // internal: the reader inspect uses
#include "printer_profiles/zip_writer.hpp"  // internal: the zip writer behind every job

#include <catch2/catch.hpp>
#include <zip.h>

#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

using namespace rodfab::test;

namespace {

// Sets `signal`'s disposition (sigaction) for the scope and restores the one before, whatever leaves it.
class SignalDisposition {
public:
  SignalDisposition(int signal, void (*handler)(int)) : signal_(signal) {
    struct sigaction wanted {};
    wanted.sa_handler = handler;
    sigemptyset(&wanted.sa_mask);
    REQUIRE(::sigaction(signal_, &wanted, &saved_) == 0);
  }
  ~SignalDisposition() { ::sigaction(signal_, &saved_, nullptr); }
  SignalDisposition(const SignalDisposition&) = delete;
  SignalDisposition& operator=(const SignalDisposition&) = delete;

private:
  int signal_;
  struct sigaction saved_ {};
};

// Sets the soft limit of `resource` for the scope (the hard one stays) and restores the one before.
class SoftLimit {
public:
  SoftLimit(int resource, rlim_t soft) : resource_(resource) {
    REQUIRE(::getrlimit(resource_, &saved_) == 0);
    rlimit lowered = saved_;
    lowered.rlim_cur = soft;
    REQUIRE(::setrlimit(resource_, &lowered) == 0);
  }
  ~SoftLimit() { ::setrlimit(resource_, &saved_); }
  SoftLimit(const SoftLimit&) = delete;
  SoftLimit& operator=(const SoftLimit&) = delete;

private:
  int resource_;
  rlimit saved_{};
};

// No file of the process may grow past `bytes` in the scope: soft RLIMIT_FSIZE with SIGXFSZ ignored, so
// write() fails with EFBIG (on any thread) instead of the signal killing the process. Both are restored
// when the scope ends, also by an exception (a failed REQUIRE); the disposition is set first and
// restored last, so the limit never holds while SIGXFSZ would kill.
struct FileSizeLimit {
  explicit FileSizeLimit(rlim_t bytes) : limit{RLIMIT_FSIZE, bytes} {}
  SignalDisposition ignoreXfsz{SIGXFSZ, SIG_IGN};
  SoftLimit limit;
};

// No file of the process may grow at all in the scope.
struct NoFileGrowth : FileSizeLimit {
  NoFileGrowth() : FileSizeLimit(0) {}
};

// The soft RLIMIT_FSIZE and SIGXFSZ's handler as they are.
std::pair<rlim_t, void (*)(int)> fileGrowthState() {
  rlimit limit{};
  REQUIRE(::getrlimit(RLIMIT_FSIZE, &limit) == 0);
  struct sigaction current {};
  REQUIRE(::sigaction(SIGXFSZ, nullptr, &current) == 0);
  return {limit.rlim_cur, current.sa_handler};
}

}  // namespace

TEST_CASE("NoFileGrowth holds while its scope runs and restores the limit and SIGXFSZ, also on an exception", "[job]") {
  const SignalDisposition knownStart{SIGXFSZ, SIG_DFL};  // whatever the runner set, so that the restoration is seen
  const auto before = fileGrowthState();
  std::pair<rlim_t, void (*)(int)> inside{};
  try {
    const NoFileGrowth guard;
    inside = fileGrowthState();  // checked after the scope: a report written under the limit could be lost
    throw std::runtime_error("a failed check inside the scope");
  } catch (const std::runtime_error&) {
  }
  CHECK(inside == std::pair<rlim_t, void (*)(int)>{0, SIG_IGN});
  CHECK(fileGrowthState() == before);
}

TEST_CASE("A write of the zip that fails fails the archive, naming the file and the reason, and leaves nothing", "[job][zip][atomic]") {
  const fs::path dir = scratch("zip-write");
  // Three incompressible 5 MiB entries, stored: a 15 MiB archive, written out in 8 MiB blocks.
  std::mt19937 rng(3);
  std::vector<Bytes> contents(3, Bytes(5u << 20));
  for (Bytes& c : contents)
    for (std::uint8_t& b : c) b = static_cast<std::uint8_t>(rng());
  std::vector<ZipMemoryEntry> entries;
  for (std::size_t n = 0; n < contents.size(); ++n) entries.push_back({"e" + std::to_string(n) + ".bin", contents[n], ZipStorage::Store});
  // 1 MiB: the first block fails; 12 MiB: the first block is written, the last fails (at the commit).
  for (const rlim_t limit : {rlim_t{1} << 20, rlim_t{12} << 20}) {
    INFO("file size limit " << limit << " bytes");
    std::string why = "no error";
    {
      const FileSizeLimit guard(limit);
      try {
        writeZipFromMemory(dir / "big.zip", entries);
      } catch (const std::exception& e) {  // checked once the limit is lifted
        why = e.what();
      }
    }
    CHECK_THAT(why, Catch::Contains((dir / "big.zip").string() + ": cannot write the archive") && Catch::Contains("File too large"));
    CHECK(fs::is_empty(dir));  // neither the archive nor its .part
  }
  // Without the limit the same entries make a whole archive, read back as written.
  writeZipFromMemory(dir / "big.zip", entries);
  const std::unique_ptr<JobReader> reader = openJobReader(dir / "big.zip", 10, 1);
  REQUIRE(reader->entries().size() == contents.size());
  for (std::size_t n = 0; n < contents.size(); ++n) CHECK((reader->read(reader->entries()[n], 6u << 20) == contents[n]));
  fs::remove_all(dir);
}

TEST_CASE("An existing job is not overwritten without force", "[job]") {
  const fs::path dir = scratch("force");
  const auto grid = overhangPart(16);
  writeJob(*grid, specFor(*grid, dir / "job.zip"), 24);
  const Bytes before = readAll(dir / "job.zip");
  CHECK_THROWS_WITH(writeJob(*grid, specFor(*grid, dir / "job.zip"), 24), Catch::Contains("--force"));
  CHECK(readAll(dir / "job.zip") == before);
  const auto other = overhangPart(17);
  JobSpec spec = specFor(*other, dir / "job.zip");
  spec.options.force = true;
  writeJob(*other, spec, 24);
  CHECK((decodeJob(dir / "job.zip") == gridVoxels(*other)));
}

TEST_CASE("A refused band leaves the writer as it was: the right band is taken next, and the job is the grid's", "[job]") {
  const fs::path dir = scratch("refused-band");
  const auto grid = overhangPart(18);
  const openvdb::CoordBBox part = grid->evalActiveVoxelBoundingBox();
  {
    JobWriter writer(specFor(*grid, dir / "job.zip"));
    CHECK_THROWS_WITH(writer.addBand({band(*grid, 3, 12), nullptr, 3, 10}), Catch::Contains("outside the band"));
    // A voxel beside the part's columns, in a leaf whose other voxels are all inside.
    const auto wide = band(*grid, 3, 10);
    wide->tree().setValueOn(openvdb::Coord(part.max().x() + 1, part.min().y(), 5), true);
    CHECK_THROWS_WITH(writer.addBand({wide, nullptr, 3, 10}), Catch::Contains("outside the band"));
    for (int k = part.min().z(); k <= part.max().z(); k += 7) {
      const int end = std::min(k + 7, part.max().z() + 1);
      writer.addBand({band(*grid, k, end), nullptr, k, end});
    }
    writer.finalize();
  }
  CHECK((decodeJob(dir / "job.zip") == gridVoxels(*grid)));
}

TEST_CASE("A failed or interrupted write leaves nothing that looks like a job", "[job][atomic]") {
  const fs::path dir = scratch("interrupt");
  const auto grid = overhangPart(18);
  const auto leftovers = [&] { return std::distance(fs::directory_iterator(dir), fs::directory_iterator()); };

  SECTION("the writer is dropped before finalize") {
    {
      JobWriter writer(specFor(*grid, dir / "job.zip"));
      writer.addBand({band(*grid, 3, 10), nullptr, 3, 10});
    }
    CHECK(leftovers() == 0);
  }
  SECTION("a band with voxels outside its layers is refused and nothing stays") {
    {
      JobWriter writer(specFor(*grid, dir / "job.zip"));
      CHECK_THROWS_WITH(writer.addBand({band(*grid, 3, 12), nullptr, 3, 10}), Catch::Contains("outside the band"));
    }
    CHECK(leftovers() == 0);
  }
  SECTION("finalize before every layer came") {
    {
      JobWriter writer(specFor(*grid, dir / "job.zip"));
      writer.addBand({band(*grid, 3, 10), nullptr, 3, 10});
      CHECK_THROWS_WITH(writer.finalize(), Catch::Contains("never added"));
    }
    CHECK(leftovers() == 0);
  }
  SECTION("writing the staged layers (layers.bin) fails: the error names the file") {
    // No file may grow while the job is written (NoFileGrowth), and every zip form is staged in the file
    // rather than kept in memory. In this process, not a forked child: a child of a process whose TBB
    // workers are running can wait for them forever.
    JobSpec spec = specFor(*grid, dir / "job.zip");
    spec.options.zipFormsInMemory = 0;
    std::string why = "no error";
    {
      const NoFileGrowth guard;
      try {
        writeJob(*grid, spec, 8);
      } catch (const std::exception& e) {  // any, and checked once the limit is lifted (a report may be a file)
        why = e.what();
      }
    }
    CHECK_THAT(why, Catch::Contains("layers.bin: cannot write"));
    CHECK(leftovers() == 0);
  }
  SECTION("the process is killed mid-job") {
    const pid_t child = ::fork();
    REQUIRE(child >= 0);
    if (child == 0) {
      JobWriter writer(specFor(*grid, dir / "job.zip"));
      writer.addBand({band(*grid, 3, 10), nullptr, 3, 10});
      writer.addBand({band(*grid, 10, 20), nullptr, 10, 20});
      ::raise(SIGKILL);
    }
    int status = 0;
    ::waitpid(child, &status, 0);
    REQUIRE(WIFSIGNALED(status));
    CHECK_FALSE(fs::exists(dir / "job.zip"));
    for (const auto& e : fs::directory_iterator(dir)) {
      CHECK(e.path().filename().string().starts_with(".job.zip.rodfab-partial-"));
      CHECK_FALSE(inspectJob(e.path()).ok());
    }
    // The next job for the same target clears the dead writer's leftovers.
    writeJob(*grid, specFor(*grid, dir / "job.zip"), 24);
    CHECK(leftovers() == 1);
  }
}


namespace {

// Everything below `root` without following links: relative path -> kind and contents (bytes or link
// target), so a folder can be compared byte for byte before and after.
std::map<std::string, std::string> snapshot(const fs::path& root) {
  std::map<std::string, std::string> out;
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator(); ++it) {
    const std::string name = fs::relative(it->path(), root).generic_string();
    const fs::file_status status = it->symlink_status();
    if (fs::is_symlink(status)) out[name] = "link:" + fs::read_symlink(it->path()).string();
    else if (fs::is_directory(status)) out[name] = "dir";
    else if (!fs::is_regular_file(status)) out[name] = "special";
    else {
      const Bytes data = readAll(it->path());
      out[name] = "file:" + std::string(data.begin(), data.end());
    }
  }
  return out;
}

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

TEST_CASE("An interrupt at any check of finalize leaves the target as it was", "[job][atomic][interrupt]") {
  const fs::path dir = scratch("interrupt-checks");
  const auto first = overhangPart(24), second = overhangPart(25);
  struct Stop {};
  for (const ArchiveFormat format : {ArchiveFormat::Zip, ArchiveFormat::Directory})
    for (const bool replacing : {false, true}) {
      fs::remove_all(dir);
      fs::create_directories(dir);
      if (replacing) writeJob(*first, specFor(*first, dir / "job.zip"), 24);
      const auto before = snapshot(dir);
      // Checks: as finalize begins, after the zip is built (zip jobs), before the rename, after it.
      const int checks = format == ArchiveFormat::Zip ? 4 : 3;
      for (int stopAt = 1; stopAt <= checks; ++stopAt) {
        INFO(toString(format) << (replacing ? ", replacing a job" : ", new target") << ", interrupted at check " << stopAt);
        int calls = 0;
        JobSpec spec = specFor(*second, dir / "job.zip");
        spec.options.archive = format;
        spec.options.force = replacing;
        spec.options.checkInterrupt = [&] {
          if (++calls == stopAt) throw Stop{};
        };
        CHECK_THROWS_AS(writeJob(*second, spec, 24), Stop);
        CHECK(calls == stopAt);
        CHECK((snapshot(dir) == before));  // the old job back, or nothing; no temporaries
      }
      int calls = 0;
      JobSpec spec = specFor(*second, dir / "job.zip");
      spec.options.archive = format;
      spec.options.force = replacing;
      spec.options.checkInterrupt = [&] { ++calls; };
      const JobResult result = writeJob(*second, spec, 24);
      CHECK(calls == checks);
      CHECK((decodeJob(dir / "job.zip") == gridVoxels(*second)));
      // Taken back after finalize returned (a late signal): only our own job is removed.
      CHECK(withdrawJob(result));
      CHECK(fs::is_empty(dir));
      CHECK_FALSE(withdrawJob(result));
    }
}

TEST_CASE("withdrawJob removes nothing that is not the job it wrote", "[job][interrupt]") {
  const fs::path dir = scratch("withdraw");
  const auto grid = overhangPart(26);
  const JobResult result = writeJob(*grid, specFor(*grid, dir / "job.zip"), 24);
  fs::rename(dir / "job.zip", dir / "moved.zip");
  writeAll(dir / "job.zip", Bytes{'u', 's', 'e', 'r'});  // someone else's file now has the name
  CHECK_FALSE(withdrawJob(result));
  CHECK((readAll(dir / "job.zip") == Bytes{'u', 's', 'e', 'r'}));
  CHECK(fs::exists(dir / "moved.zip"));
}

TEST_CASE("Staging folders of dead writers go, whatever their target; live ones and strangers stay", "[job][atomic]") {
  const fs::path dir = scratch("stale-staging");
  const auto grid = overhangPart(27);
  // A writer killed mid-job (SIGKILL: no cleanup at all).
  const pid_t killed = ::fork();
  REQUIRE(killed >= 0);
  if (killed == 0) {
    JobWriter writer(specFor(*grid, dir / "killed.zip"));
    writer.addBand({band(*grid, 3, 10), nullptr, 3, 10});
    writer.addBand({band(*grid, 10, 20), nullptr, 10, 20});
    ::raise(SIGKILL);
  }
  int status = 0;
  ::waitpid(killed, &status, 0);
  REQUIRE(WIFSIGNALED(status));
  std::vector<fs::path> dead;
  for (const auto& e : fs::directory_iterator(dir)) dead.push_back(e.path());
  REQUIRE(dead.size() == 1);
  CHECK(dead[0].filename().string().starts_with(".killed.zip.rodfab-partial-" + std::to_string(killed) + "-"));
  CHECK_FALSE(inspectJob(dead[0]).ok());

  // A live writer in another process, holding its staging folder while this one writes.
  int toChild[2], toParent[2];
  REQUIRE(::pipe(toChild) == 0);
  REQUIRE(::pipe(toParent) == 0);
  const pid_t live = ::fork();
  REQUIRE(live >= 0);
  if (live == 0) {
    JobWriter writer(specFor(*grid, dir / "live.zip"));
    char c = 'r';
    if (::write(toParent[1], &c, 1) != 1 || ::read(toChild[0], &c, 1) != 1) ::_exit(2);
    for (int k = 3; k < 27; k += 8) writer.addBand({band(*grid, k, std::min(k + 8, 27)), nullptr, k, std::min(k + 8, 27)});
    writer.finalize();
    ::_exit(0);
  }
  char c = 0;
  REQUIRE(::read(toParent[0], &c, 1) == 1);
  // Strangers: names that only look like ours, a lock-less folder of a live pid (ours), a held lock.
  fs::create_directories(dir / ".notes.rodfab-partial-abc");
  fs::create_directories(dir / ".x.zip.rodfab-partial-" / "keep");
  fs::create_directories(dir / ("..rodfab-partial-" + std::to_string(killed) + "-0"));
  fs::create_directories(dir / (".mine.zip.rodfab-partial-" + std::to_string(::getpid()) + "-7"));
  writeAll(dir / ".user.rodfab-partial-1-2.txt", Bytes{'u'});
  const std::set<std::string> strangers = {".notes.rodfab-partial-abc", ".x.zip.rodfab-partial-",
                                           "..rodfab-partial-" + std::to_string(killed) + "-0",
                                           ".mine.zip.rodfab-partial-" + std::to_string(::getpid()) + "-7",
                                           ".user.rodfab-partial-1-2.txt"};
  // An older version's lock-less folder of a dead pid goes.
  fs::create_directories(dir / (".old.zip.rodfab-partial-" + std::to_string(killed) + "-3") / "previews");

  writeJob(*grid, specFor(*grid, dir / "other.zip"), 24);  // another target name in the same folder
  std::set<std::string> left;
  for (const auto& e : fs::directory_iterator(dir)) left.insert(e.path().filename().string());
  for (const std::string& s : strangers) CHECK(left.contains(s));
  CHECK(left.contains("other.zip"));
  CHECK_FALSE(left.contains(dead[0].filename().string()));
  CHECK(std::count_if(left.begin(), left.end(), [&](const std::string& n) { return n.starts_with(".live.zip.rodfab-partial-"); }) == 1);
  CHECK(left.size() == strangers.size() + 2);  // + other.zip + the live writer's staging folder

  REQUIRE(::write(toChild[1], &c, 1) == 1);  // the live writer finishes its job undisturbed
  ::waitpid(live, &status, 0);
  CHECK((WIFEXITED(status) && WEXITSTATUS(status) == 0));
  CHECK((decodeJob(dir / "live.zip") == gridVoxels(*grid)));
  for (int fd : {toChild[0], toChild[1], toParent[0], toParent[1]}) ::close(fd);
}

