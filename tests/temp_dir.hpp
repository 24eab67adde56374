// Folders for tests' files under the system's temporary folder, removed with everything in them, so a
// test run leaves nothing behind (three suites left ~1 MB a run in /tmp before).
#pragma once

#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <string>

namespace rodfab::test {

// A new, empty folder `rodfab-test-SUITE-PID-N`, removed when the object goes.
struct TempDir {
  std::filesystem::path path;
  explicit TempDir(const std::string& suite = "scratch") {
    static std::atomic<int> counter{0};
    path = std::filesystem::temp_directory_path() /
           ("rodfab-test-" + suite + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TempDir() {
    std::error_code ignored;  // a destructor must not throw; what is left is the system's to clean
    std::filesystem::remove_all(path, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

// `name` in a folder of `suite`'s that lives as long as the test process (made on first use, removed
// at exit), for helpers that hand out file names.
inline std::filesystem::path processScratch(const std::string& suite, const std::string& name) {
  static const TempDir folder(suite);
  return folder.path / name;
}

}  // namespace rodfab::test
