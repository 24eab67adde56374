// printer_profiles/ jobs on disk: a job replaces another only with force (what force may replace:
// test_printer_jobs_force.cpp), a failed or interrupted write leaves nothing that looks like a job and
// the target as it was, withdrawJob and the removal of dead writers' staging folders touch nothing else. Helpers: tests/printer_jobs_fixture.hpp.
#include "tests/file_size_limit.hpp"
#include "tests/printer_jobs_fixture.hpp"

#include "printer_profiles/job_reader.hpp"  // internal: the reader inspect uses
#include "printer_profiles/zip_writer.hpp"  // internal: the zip writer behind every job

#include <catch2/catch.hpp>

#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>

using namespace rodfab::test;

namespace {

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

TEST_CASE("Staging folders of dead writers go, whatever their target, live ones and strangers stay", "[job][atomic]") {
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
  // Named exactly like ours, of a dead pid, but holding what no staging folder holds, or a file that
  // is not an older version's temporary zip: someone's (both were removed).
  const std::string thesis = ".thesis.zip.rodfab-partial-" + std::to_string(killed) + "-5";
  const std::string plain = ".b.zip.rodfab-partial-" + std::to_string(killed) + "-6";
  fs::create_directories(dir / thesis / "previews");
  writeAll(dir / thesis / "thesis.txt", Bytes{'m', 'y'});
  writeAll(dir / plain, Bytes{'u'});
  const std::set<std::string> strangers = {".notes.rodfab-partial-abc", ".x.zip.rodfab-partial-",
                                           "..rodfab-partial-" + std::to_string(killed) + "-0",
                                           ".mine.zip.rodfab-partial-" + std::to_string(::getpid()) + "-7",
                                           ".user.rodfab-partial-1-2.txt", thesis, plain};
  // An older version's lock-less folder of a dead pid goes.
  fs::create_directories(dir / (".old.zip.rodfab-partial-" + std::to_string(killed) + "-3") / "previews");

  writeJob(*grid, specFor(*grid, dir / "other.zip"), 24);  // another target name in the same folder
  std::set<std::string> left;
  for (const auto& e : fs::directory_iterator(dir)) left.insert(e.path().filename().string());
  for (const std::string& s : strangers) CHECK(left.contains(s));
  CHECK((readAll(dir / thesis / "thesis.txt") == Bytes{'m', 'y'}));
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


TEST_CASE("A job a dead writer had moved aside to replace it is put back, not removed with its staging", "[job][atomic]") {
  // Without RENAME_EXCHANGE (vfat, exFAT, NFS) the commit moves the old job into the staging folder
  // ("replaced"), then renames the new one into place: SIGKILL between the two left neither under the
  // output's name, and the next run in the folder removed the staging folder with the only copy.
  const fs::path dir = scratch("replaced-recovery");
  const auto grid = overhangPart(26);
  writeJob(*grid, specFor(*grid, dir / "seed.zip"), 24);
  const Bytes old = readAll(dir / "seed.zip");
  const pid_t dead = ::fork();
  REQUIRE(dead >= 0);
  if (dead == 0) ::_exit(0);
  int status = 0;
  ::waitpid(dead, &status, 0);
  const std::string pid = std::to_string(dead);
  for (const std::string target : {"lost.zip", "taken.zip", "clash.zip"}) {
    const fs::path staging = dir / ("." + target + ".rodfab-partial-" + pid + "-0");
    fs::create_directories(staging / "previews");
    fs::copy_file(dir / "seed.zip", staging / "replaced");
  }
  writeAll(dir / "taken.zip", Bytes{'n', 'e', 'w'});  // the name taken since (by hand, or a later run)
  writeAll(dir / "clash.zip", Bytes{'n', 'e', 'w'});  // and the first previous-version name too (a pid reused)
  writeAll(dir / (".clash.zip.rodfab-old-" + pid + "-0"), Bytes{'e', 'a', 'r', 'l', 'i', 'e', 'r'});
  writeJob(*grid, specFor(*grid, dir / "other.zip"), 24);  // any run in the folder cleans dead staging
  CHECK(readAll(dir / "lost.zip") == old);
  CHECK(inspectJob(dir / "lost.zip").ok());
  CHECK((readAll(dir / "taken.zip") == Bytes{'n', 'e', 'w'}));
  CHECK(readAll(dir / (".taken.zip.rodfab-old-" + pid + "-0")) == old);
  CHECK((readAll(dir / (".clash.zip.rodfab-old-" + pid + "-0")) == Bytes{'e', 'a', 'r', 'l', 'i', 'e', 'r'}));
  CHECK(readAll(dir / (".clash.zip.rodfab-old-" + pid + "-1")) == old);
  for (const auto& e : fs::directory_iterator(dir)) CHECK_FALSE(e.path().filename().string().find(".rodfab-partial-") != std::string::npos);
}

TEST_CASE("An output whose staging files would pass the system's path limit is refused before any work", "[job][atomic]") {
  // A 3,900-byte folder path: the job's name fits, but its staging folder's previews would not
  // (ENAMETOOLONG after the whole slice, said as "disk full or no permission?").
  fs::path deep = scratch("deep-output");
  while (deep.string().size() < 3900) deep /= std::string(60, 'd');
  fs::create_directories(deep);
  const auto grid = overhangPart(12);
  CHECK_THROWS_WITH(JobWriter(specFor(*grid, deep / "j.zip")), Catch::Contains("j.zip: the path is ") &&
                                                                   Catch::Contains("bytes deeper, and the system allows paths of at most 4095"));
  CHECK(fs::is_empty(deep));
}
