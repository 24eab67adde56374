// common/: saturatedBytes at the ends of the range, requireMemory's refusal message, SHA-256 against the FIPS 180-2 test vectors, XXH3-128 against xxhsum -H2 (in one piece and through FileHasher), the data folder's search order and errors.
#include "common/data_dir.hpp"
#include "common/file_hasher.hpp"
#include "common/local_time_zone.hpp"
#include "common/located_issues.hpp"
#include "common/memory_budget.hpp"
#include "common/output_file.hpp"
#include "common/quoted_text.hpp"
#include "common/sha256.hpp"
#include "common/xxh128.hpp"

#include <catch2/catch.hpp>

#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <span>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace rodfab::common;

TEST_CASE("SHA-256 gives the FIPS 180-2 digests, in one piece or streamed") {
  CHECK(sha256Hex(std::string_view("abc")) == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  CHECK(sha256Hex(std::string_view("")) == "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  const std::string twoBlocks = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
  CHECK(sha256Hex(std::string_view(twoBlocks)) == "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  FileHasher streamed(HashAlgorithm::Sha256);
  const std::vector<std::uint8_t> bytes(twoBlocks.begin(), twoBlocks.end());
  streamed.update(std::span(bytes).first(7));
  streamed.update(std::span(bytes).subspan(7));
  CHECK(streamed.hex() == sha256Hex(std::span<const std::uint8_t>(bytes)));
  CHECK(isSha256Hex(sha256Hex(std::string_view("x"))));
  CHECK_FALSE(isSha256Hex("BA7816BF8F01CFEA414140DE5DAE2223B00361A396177A9CB410FF61F20015AD"));
  CHECK_FALSE(isSha256Hex("abc"));
}

// The digests `xxhsum -H2` (Debian package xxhash) prints for the same inputs.
TEST_CASE("XXH3-128 gives xxhsum's digests, in one piece or streamed") {
  CHECK(xxh128Hex(std::string_view("")) == "99aa06d3014798d86001c324468d497f");
  CHECK(xxh128Hex(std::string_view("abc")) == "06b05ab6733a618578af5f94892f3950");
  const std::vector<std::uint8_t> zeros(1000000, 0);
  CHECK(xxh128Hex(std::span<const std::uint8_t>(zeros)) == "ef233fc372a159319d648391f361d99a");
  FileHasher streamed(HashAlgorithm::Xxh128);  // split across XXH3's internal 256-byte stripes and its buffer
  for (const std::size_t piece : {1u, 255u, 4096u, 70000u}) streamed.update(std::span(zeros).first(piece));
  streamed.update(std::span(zeros).subspan(1 + 255 + 4096 + 70000));
  CHECK(streamed.hex() == "ef233fc372a159319d648391f361d99a");
  CHECK(isXxh128Hex(xxh128Hex(std::string_view("x"))));
  CHECK_FALSE(isXxh128Hex("06B05AB6733A618578AF5F94892F3950"));
  CHECK_FALSE(isXxh128Hex(sha256Hex(std::string_view("abc"))));
}

TEST_CASE("the data folder is looked for beside the executable, one to three levels up") {
  const auto c = dataDirCandidates("/opt/x/bin/rodfab");
  REQUIRE(c.size() == 3);
  CHECK(c[0] == fs::path("/opt/x/share/rodfab"));
  CHECK(c[1] == fs::path("/opt/share/rodfab"));
  CHECK(c[2] == fs::path("/share/rodfab"));
  CHECK(dataDirCandidates("/rodfab").empty());  // no folder above /
}

namespace {

struct EnvGuard {
  std::string old;
  bool had;
  EnvGuard() : had(std::getenv(kDataDirVariable) != nullptr) {
    if (had) old = std::getenv(kDataDirVariable);
  }
  ~EnvGuard() {
    if (had) ::setenv(kDataDirVariable, old.c_str(), 1);
    else ::unsetenv(kDataDirVariable);
  }
};

}  // namespace

TEST_CASE("RODFAB_DATA_DIR overrides the search, and a wrong one is an error naming it") {
  EnvGuard guard;
  const fs::path tmp = fs::temp_directory_path() / ("rodfab-data-dir-test-" + std::to_string(::getpid()));
  fs::remove_all(tmp);
  fs::create_directories(tmp / "profiles");
  std::ofstream(tmp / "profiles" / "p.json") << "{}";
  ::setenv(kDataDirVariable, tmp.c_str(), 1);
  CHECK(dataDir() == tmp);
  CHECK(dataFile("profiles/p.json") == tmp / "profiles" / "p.json");
  try {
    dataFile("masks/none.rfbn");
    FAIL("a missing data file was found");
  } catch (const DataDirError& e) {
    CHECK(std::string(e.what()).find("masks/none.rfbn") != std::string::npos);
  }
  ::setenv(kDataDirVariable, (tmp / "nowhere").c_str(), 1);
  try {
    dataDir();
    FAIL("a wrong RODFAB_DATA_DIR was accepted");
  } catch (const DataDirError& e) {
    CHECK(std::string(e.what()).find("RODFAB_DATA_DIR is '" + (tmp / "nowhere").string() + "'") != std::string::npos);
  }
  fs::remove_all(tmp);
}

TEST_CASE("without RODFAB_DATA_DIR, a test in the build tree finds the build tree's data folder") {
  EnvGuard guard;
  ::unsetenv(kDataDirVariable);
  const fs::path dir = dataDir();
  CHECK(fs::is_regular_file(dir / "calibration" / "default-60C.json"));
  CHECK(fs::is_directory(dir / "masks"));
  CHECK(dir.filename() == "rodfab");
}

TEST_CASE("located issues: one line each, FILE: PATH: MESSAGE, the path left out for the whole file") {
  struct Issue {
    std::string path, message;
  };
  CHECK(rodfab::common::formatLocatedIssues("d.json", std::vector<Issue>{}).empty());
  CHECK(rodfab::common::formatLocatedIssues("d.json", std::vector<Issue>{{"", "cannot open"}}) == "d.json: cannot open");
  CHECK(rodfab::common::formatLocatedIssues("d.json", std::vector<Issue>{{"rods[0].name", "missing"}, {"units", "expected \"mm\""}}) ==
        "d.json: rods[0].name: missing\nd.json: units: expected \"mm\"");
}

TEST_CASE("a cut issue list counts the issues it shows, not its cut line, and says more were found") {
  struct Issue {
    std::string path, message;
  };
  std::vector<Issue> issues;
  rodfab::common::listIssue(issues, Issue{"a", "bad"});
  CHECK(rodfab::common::issueCountText(issues) == "1 error");
  for (std::size_t n = 1; n < kMaxListedIssues; ++n) rodfab::common::listIssue(issues, Issue{"a", "bad"});
  // Exactly the most listed: nothing cut, the true count.
  REQUIRE(issues.size() == kMaxListedIssues);
  CHECK_FALSE(rodfab::common::issueListCut(issues));
  CHECK(rodfab::common::issueCountText(issues) == "100 errors");
  // One more: the cut line is added, and is not an error.
  rodfab::common::listIssue(issues, Issue{"a", "bad"});
  rodfab::common::listIssue(issues, Issue{"a", "bad"});
  REQUIRE(issues.size() == kMaxListedIssues + 1);
  CHECK(rodfab::common::listedIssueCount(issues) == kMaxListedIssues);
  CHECK(rodfab::common::issueCountText(issues) == "100 errors shown, more were found");
}

TEST_CASE("memory budget: saturatedBytes: NaN, infinity and 2^64 or more are UINT64_MAX, negatives 0, the rest rounded down") {
  constexpr double kTwoTo64 = 18446744073709551616.0;
  const double inf = std::numeric_limits<double>::infinity();
  CHECK(saturatedBytes(std::nan("")) == UINT64_MAX);
  CHECK(saturatedBytes(inf) == UINT64_MAX);
  CHECK(saturatedBytes(kTwoTo64) == UINT64_MAX);
  CHECK(saturatedBytes(1e300) == UINT64_MAX);
  CHECK(saturatedBytes(-inf) == 0);
  CHECK(saturatedBytes(-1.0) == 0);
  CHECK(saturatedBytes(-0.0) == 0);
  CHECK(saturatedBytes(0.0) == 0);
  CHECK(saturatedBytes(0.999) == 0);
  CHECK(saturatedBytes(1536.7) == 1536);
  // The largest double below 2^64 is 2^64 - 2048: it still counts, exactly.
  const double below = std::nextafter(kTwoTo64, 0.0);
  CHECK(saturatedBytes(below) == UINT64_MAX - 2047);
  CHECK(saturatedBytes(1.8e19) == std::uint64_t{18000000000000000000u});  // the old, lower, cap is an ordinary value now
}

TEST_CASE("memory budget: requireMemory passes up to the budget and beyond it names the work, the figures and the remedy") {
  // The budget is read, never set here: setMemoryBudget would also lower the test process's data limit.
  const std::uint64_t budget = memoryBudget();
  const std::string of = "more than the memory budget of " + formatBytes(budget) + " (--max-memory); ";
  CHECK_NOTHROW(requireMemory(budget, {.what = "w", .remedy = "r"}));
  CHECK_NOTHROW(requireMemory(0, {.what = "w", .condition = "c", .remedy = "r"}));
  const std::uint64_t over = 3 * (std::uint64_t{1} << 40);  // 3 TiB, above any budget this machine gives
  REQUIRE(over > budget);
  CHECK_THROWS_MATCHES(requireMemory(over, {.what = "slicing x.json", .remedy = "use fewer --band-layers"}), OutOfMemory,
                       Catch::Message("out of memory: slicing x.json needs about 3072.0 GiB, " + of +
                                                "use fewer --band-layers"));
  CHECK_THROWS_MATCHES(requireMemory(over, {.what = "slicing x.json", .condition = "even in bands of 1 layer", .remedy = "r"}),
                       OutOfMemory,
                       Catch::Message("out of memory: slicing x.json needs about 3072.0 GiB even in bands of 1 layer, " + of + "r"));
}

// In a child process: setMemoryBudget lowers the process's data limit for good.
TEST_CASE("memory budget: the data limit is lifted while a DataLimitLifted lives, and comes back with the last") {
#if defined(__SANITIZE_ADDRESS__)
  WARN("no data limit under AddressSanitizer");
  return;
#endif
  const pid_t child = ::fork();
  REQUIRE(child >= 0);
  if (child == 0) {
    const auto soft = [] {
      rlimit l{};
      ::getrlimit(RLIMIT_DATA, &l);
      return l;
    };
    const rlim_t hard = soft().rlim_max, budget = rlim_t{512} << 20;
    setMemoryBudget(budget);
    int failures = soft().rlim_cur != budget || soft().rlim_max != hard;
    {
      const DataLimitLifted outer;
      failures += soft().rlim_cur != hard;
      {
        const DataLimitLifted inner;
        failures += soft().rlim_cur != hard;
      }
      failures += soft().rlim_cur != hard;  // the outer one still lives
    }
    failures += soft().rlim_cur != budget;
    ::_exit(failures);
  }
  int status = 0;
  REQUIRE(::waitpid(child, &status, 0) == child);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
}

TEST_CASE("keepLocalTimeZone names glibc's default zone file only when TZ is unset, and times stay as they were") {
  const char* before = std::getenv("TZ");
  const std::string saved = before ? before : "";
  const auto localTimeOf = [] {
    std::tm t{};
    t.tm_year = 120, t.tm_mon = 6, t.tm_mday = 1, t.tm_hour = 12, t.tm_isdst = -1;  // 2020-07-01 12:00, in summer time where there is one
    return std::mktime(&t);
  };
  ::unsetenv("TZ");
  const std::time_t unset = localTimeOf();
  rodfab::common::keepLocalTimeZone();
  REQUIRE(std::getenv("TZ") != nullptr);
  CHECK(std::string(std::getenv("TZ")) == ":/etc/localtime");
  CHECK(localTimeOf() == unset);
  ::setenv("TZ", "UTC0", 1);
  rodfab::common::keepLocalTimeZone();
  CHECK(std::string(std::getenv("TZ")) == "UTC0");
  if (before) ::setenv("TZ", saved.c_str(), 1);
  else ::unsetenv("TZ");
  ::tzset();
}

TEST_CASE("a sealed JSON object is told from one a person wrote or edited, and from anything that is not a plain file") {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("rodfab-seal-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name, std::ios::binary) << text;
    return dir / name;
  };
  const std::string members = "  \"format\": \"rodfab.design/1\",\n  \"rods\": []\n}\n";
  const std::string sealed = rodfab::common::sealJsonObject(members);
  // The seal is the object's first member, the XXH3-128 (as xxhsum -H2 prints it) of what follows its line.
  REQUIRE(sealed == "{\n  \"written_by\": \"rodfab, xxh128 " + rodfab::common::xxh128Hex(members) + "\",\n" + members);
  CHECK(rodfab::common::isSealedJsonObject(write("ours.json", sealed)));
  CHECK_FALSE(rodfab::common::isSealedJsonObject(dir / "ours.json", sealed.size() - 1));  // longer than allowed
  // One byte changed anywhere after the seal, or in the digest, or the seal missing: not ours.
  std::string edited = sealed;
  edited[edited.size() - 4] = 'X';
  CHECK_FALSE(rodfab::common::isSealedJsonObject(write("edited.json", edited)));
  std::string digest = sealed;
  digest[40] = digest[40] == '0' ? '1' : '0';
  CHECK_FALSE(rodfab::common::isSealedJsonObject(write("digest.json", digest)));
  CHECK_FALSE(rodfab::common::isSealedJsonObject(write("mine.json", "{\n" + members)));
  CHECK_FALSE(rodfab::common::isSealedJsonObject(write("short.json", sealed.substr(0, 30))));
  CHECK_FALSE(rodfab::common::isSealedJsonObject(write("empty.json", "")));
  // A link to a sealed file, a folder, a pipe and a missing file are never ours (and never block).
  std::filesystem::create_symlink(dir / "ours.json", dir / "link.json");
  CHECK_FALSE(rodfab::common::isSealedJsonObject(dir / "link.json"));
  CHECK_FALSE(rodfab::common::isSealedJsonObject(dir));
  REQUIRE(::mkfifo((dir / "pipe").c_str(), 0600) == 0);
  CHECK_FALSE(rodfab::common::isSealedJsonObject(dir / "pipe"));
  CHECK_FALSE(rodfab::common::isSealedJsonObject(dir / "missing.json"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("a file's text in a message: control bytes and invalid UTF-8 escaped, UTF-8 kept, long text cut") {
  using rodfab::common::printableFromFile;
  using rodfab::common::quotedFromFile;
  CHECK(quotedFromFile("floz") == "'floz'");
  CHECK(quotedFromFile("") == "''");
  // An ANSI sequence (clear the screen), a tab, DEL, the quote and the backslash.
  CHECK(quotedFromFile("x\x1b[2J\ty\x7f'\\") == "'x\\x1b[2J\\x09y\\x7f\\x27\\x5c'");
  // UTF-8 kept: e acute, the euro sign, a 4-byte emoji.
  CHECK(printableFromFile("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80") == "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80");
  // The C1 control CSI (U+009B, which some terminals obey) and malformed UTF-8: a lone continuation
  // byte, a lead byte cut short, an overlong slash, a surrogate.
  CHECK(printableFromFile("\xc2\x9b") == "\\xc2\\x9b");
  CHECK(printableFromFile("a\x80" "b\xe2\x82") == "a\\x80b\\xe2\\x82");
  CHECK(printableFromFile("\xc0\xaf\xed\xa0\x80") == "\\xc0\\xaf\\xed\\xa0\\x80");
  // Cut after maxBytes bytes of the text, marked.
  CHECK(quotedFromFile(std::string(100, 'a'), 8) == "'aaaaaaaa...'");
  CHECK(printableFromFile("abcdefgh", 8) == "abcdefgh");
  CHECK(printableFromFile(std::string("a\0b", 3)) == "a\\x00b");
}
