#include "common/data_dir.hpp"

#include <cstdlib>
#include <system_error>

namespace rodfab::common {

namespace fs = std::filesystem;

namespace {

bool isDataDir(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir / "profiles", ec);
}

// The running executable, links resolved; empty when /proc is not mounted.
fs::path runningExecutable() {
  std::error_code ec;
  fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path() : exe;
}

}  // namespace

std::vector<fs::path> dataDirCandidates(const fs::path& executable) {
  std::vector<fs::path> candidates;
  fs::path dir = executable.parent_path();
  for (int up = 0; up < 3 && dir.has_relative_path(); ++up, dir = dir.parent_path())
    candidates.push_back((dir / ".." / "share" / "rodfab").lexically_normal());
  return candidates;
}

fs::path dataDir() {
  if (const char* env = std::getenv(kDataDirVariable); env && *env) {
    if (isDataDir(env)) return env;
    throw DataDirError(std::string("rodfab's data folder was not found: $") + kDataDirVariable + " is '" + env +
                       "', which holds no profiles/ folder (expected the share/rodfab folder of an installed rodfab)");
  }
  const fs::path exe = runningExecutable();
  std::string looked;
  for (const fs::path& dir : dataDirCandidates(exe)) {
    if (isDataDir(dir)) return dir;
    looked += "\n  " + dir.string();
  }
  if (exe.empty()) looked += "\n  (none: /proc/self/exe is unreadable, so the executable's folder is unknown)";
  throw DataDirError(std::string("rodfab's data folder (profiles/, calibration/, masks/, examples/) was not found; looked in:") +
                     looked + "\nreinstall rodfab, or set $" + kDataDirVariable + " to its share/rodfab folder");
}

fs::path dataFile(const fs::path& relative) {
  const fs::path dir = dataDir();
  fs::path file = dir / relative;
  std::error_code ec;
  if (!fs::is_regular_file(file, ec))
    throw DataDirError(file.string() + ": rodfab's data file " + relative.string() + " is missing from its data folder " +
                       dir.string() + " (an incomplete installation? set $" + kDataDirVariable + " to a complete one)");
  return file;
}

}  // namespace rodfab::common
