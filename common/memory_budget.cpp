#include "common/memory_budget.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <optional>
#include <sstream>

#if defined(__SANITIZE_ADDRESS__)
#define RODFAB_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RODFAB_SANITIZED 1
#endif
#endif

namespace rodfab::common {

namespace {

constexpr std::uint64_t kMinimumBudget = std::uint64_t{64} << 20;
std::uint64_t budget = 0;
std::mutex liftMutex;
int lifts = 0;  // DataLimitLifted objects alive

// RLIMIT_DATA's soft limit to `bytes`, or to its hard limit; the hard limit is left as it is, so that
// DataLimitLifted can raise the soft one again. Not under AddressSanitizer (its shadow memory).
void setDataLimit([[maybe_unused]] std::optional<std::uint64_t> bytes) {
#ifndef RODFAB_SANITIZED
  rlimit current{};
  if (::getrlimit(RLIMIT_DATA, &current) != 0) return;
  if (!bytes) current.rlim_cur = current.rlim_max;
  else if (current.rlim_max == RLIM_INFINITY || current.rlim_max >= *bytes) current.rlim_cur = static_cast<rlim_t>(*bytes);
  else return;
  ::setrlimit(RLIMIT_DATA, &current);
#endif
}

std::uint64_t physicalMemory() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), size = ::sysconf(_SC_PAGESIZE);
  return pages > 0 && size > 0 ? static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(size) : 0;
}

std::uint64_t cgroupLimit() {
  std::ifstream in("/sys/fs/cgroup/memory.max");
  std::string text;
  if (!(in >> text) || text == "max") return 0;
  try {
    return std::stoull(text);
  } catch (...) {
    return 0;
  }
}

// A limit the process was started under (ulimit -v / -d, prlimit): the budget stays inside it.
std::uint64_t inheritedLimit() {
  std::uint64_t lowest = 0;
  for (int resource : {RLIMIT_AS, RLIMIT_DATA}) {
    rlimit limit{};
    if (::getrlimit(resource, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) continue;
    const auto bytes = static_cast<std::uint64_t>(limit.rlim_cur);
    if (lowest == 0 || bytes < lowest) lowest = bytes;
  }
  return lowest;
}

}  // namespace

std::uint64_t defaultMemoryBudget() {
  std::uint64_t total = physicalMemory();
  for (const std::uint64_t limit : {cgroupLimit(), inheritedLimit()})
    if (limit > 0 && (total == 0 || limit < total)) total = limit;
  if (total == 0) total = std::uint64_t{4} << 30;
  return std::max(kMinimumBudget, total / 5 * 4);
}

void setMemoryBudget(std::uint64_t bytes) {
  if (bytes < kMinimumBudget)
    throw std::invalid_argument("expected a memory budget of at least " + formatBytes(kMinimumBudget) + ", got " +
                                formatBytes(bytes));
  const std::lock_guard lock(liftMutex);
  budget = bytes;
  if (lifts == 0) setDataLimit(bytes);
}

DataLimitLifted::DataLimitLifted() {
  const std::lock_guard lock(liftMutex);
  if (lifts++ == 0 && budget) setDataLimit(std::nullopt);
}

DataLimitLifted::~DataLimitLifted() {
  const std::lock_guard lock(liftMutex);
  if (--lifts == 0 && budget) setDataLimit(budget);
}

std::uint64_t memoryBudget() { return budget ? budget : defaultMemoryBudget(); }

void requireMemory(std::uint64_t bytes, const MemoryNeed& need) {
  if (bytes <= memoryBudget()) return;
  throw OutOfMemory("out of memory: " + need.what + " needs about " + formatBytes(bytes) +
                    (need.condition.empty() ? "" : " " + need.condition) + ", more than the memory budget of " +
                    formatBytes(memoryBudget()) + " (--max-memory); " + need.remedy);
}

std::uint64_t saturatedBytes(double bytes) {
  constexpr double kTwoTo64 = 18446744073709551616.0;  // 2^64, exact in a double
  if (std::isnan(bytes) || bytes >= kTwoTo64) return UINT64_MAX;
  if (bytes <= 0.0) return 0;
  return static_cast<std::uint64_t>(bytes);
}

std::uint64_t dataBytesInUse() {
  std::ifstream in("/proc/self/status");
  std::string key;
  std::uint64_t kib = 0;
  while (in >> key)
    if (key == "VmData:" && in >> kib) return kib * 1024;
  return 0;
}

std::string formatBytes(std::uint64_t bytes) {
  char text[32];
  if (bytes >= (std::uint64_t{1} << 30)) std::snprintf(text, sizeof text, "%.1f GiB", static_cast<double>(bytes) / (1 << 30));
  else std::snprintf(text, sizeof text, "%.0f MiB", static_cast<double>(bytes) / (1 << 20));
  return text;
}

std::optional<std::uint64_t> parseByteSize(const std::string& text) {
  std::istringstream in(text);
  double value = 0;
  if (!(in >> value) || !std::isfinite(value) || value <= 0) return std::nullopt;
  std::string unit;
  in >> unit;
  if (!in.eof() && in.peek() != EOF) return std::nullopt;
  std::transform(unit.begin(), unit.end(), unit.begin(), [](unsigned char c) { return std::toupper(c); });
  double scale = 0;
  if (unit.empty() || unit == "B") scale = 1;
  else if (unit == "K" || unit == "KB" || unit == "KIB") scale = 1024.0;
  else if (unit == "M" || unit == "MB" || unit == "MIB") scale = 1024.0 * 1024;
  else if (unit == "G" || unit == "GB" || unit == "GIB") scale = 1024.0 * 1024 * 1024;
  else if (unit == "T" || unit == "TB" || unit == "TIB") scale = 1024.0 * 1024 * 1024 * 1024;
  else return std::nullopt;
  const double bytes = value * scale;
  if (bytes > 1e18) return std::nullopt;
  return static_cast<std::uint64_t>(bytes);
}

std::string outOfMemoryMessage() {
  return "out of memory: the work needed more than the memory budget of " + formatBytes(memoryBudget()) +
         " (--max-memory, default 80 % of this machine's memory); use a smaller design or coarser settings, "
         "or raise --max-memory if the machine has more";
}

}  // namespace rodfab::common
