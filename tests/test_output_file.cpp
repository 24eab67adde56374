// common/output_file.hpp: output paths checked before any work (a name too long for the hidden
// temporary beside it), and the files a commit replaces kept until the command ends.
#include "common/interrupt.hpp"
#include "common/output_file.hpp"
#include "tests/temp_dir.hpp"

#include <catch2/catch.hpp>

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
