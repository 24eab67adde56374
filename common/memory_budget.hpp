// The process's memory budget.
//
// Every rodfab command runs within a budget of bytes (default: 80 % of the machine's memory, or of
// the cgroup limit or the address-space/data limit it was started under when lower; `--max-memory` sets it). It is enforced twice:
//  - work whose size depends on input estimates its memory first and refuses with OutOfMemory
//    (`requireMemory`) before allocating;
//  - the budget is also the process's data limit (RLIMIT_DATA), so an allocation beyond it fails
//    with std::bad_alloc, which main reports as OutOfMemory instead of the kernel killing the
//    process (not in sanitizer builds, whose shadow memory would count against it).
// Thread safety: set the budget once at start-up, before other threads run.
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

namespace rodfab::common {

// Work that would exceed the budget. what() says how much it needs, the budget and what to change.
struct OutOfMemory : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Bytes: 80 % of physical memory, or of the cgroup's memory.max or an inherited RLIMIT_AS/RLIMIT_DATA
// when one of those is lower.
std::uint64_t defaultMemoryBudget();

// Sets the budget (bytes, >= 64 MiB) and the data limit (RLIMIT_DATA's soft limit: the backstop that
// turns an allocation past the budget into std::bad_alloc). Throws std::invalid_argument when too small.
void setMemoryBudget(std::uint64_t bytes);
std::uint64_t memoryBudget();

// While one lives, the data limit setMemoryBudget set is lifted (to the hard limit), for a library that
// cannot survive a failed allocation: cairo's scan converter jumps through a broken jmp_buf when one
// fails (a segfault in cairo_stroke at --max-memory 64M). Its work must be bounded by what the caller
// estimated or capped (a canvas of known size, a capped number of marks). Thread-safe; nests: the limit
// comes back when the last one goes.
class DataLimitLifted {
public:
  DataLimitLifted();
  ~DataLimitLifted();
  DataLimitLifted(const DataLimitLifted&) = delete;
  DataLimitLifted& operator=(const DataLimitLifted&) = delete;
};

// What a refusal says besides the figures: "out of memory: WHAT needs about N CONDITION, more than the
// memory budget of B (--max-memory); REMEDY". Filled with designated initializers:
// requireMemory(bytes, {.what = "slicing x.json", .remedy = "use fewer --band-layers"}).
// Only `condition` may be left out (its `{}` keeps -Wmissing-field-initializers quiet for it alone).
struct MemoryNeed {
  std::string what;         // the work: "voxelizing x.json into one grid in memory"
  std::string condition{};  // after the figure, e.g. "even in bands of 1 layer (the smallest band size tried)"; empty: none
  std::string remedy;       // what to change: "use a coarser --voxel-size"
};

// Throws OutOfMemory (the message above) when `bytes`, an estimate for `need.what`, exceeds the budget.
void requireMemory(std::uint64_t bytes, const MemoryNeed& need);

// An estimate in bytes worked out in double, as the unsigned count requireMemory takes: UINT64_MAX for
// NaN, +infinity and anything at or above 2^64 (an estimate too large to count is over any budget),
// 0 for negative values (and -infinity), the value rounded down otherwise. The one conversion every
// memory estimate uses, so an overflowing estimate always refuses the same way. Thread-safe (pure).
std::uint64_t saturatedBytes(double bytes);

// The process's private data now (VmData of /proc/self/status): what the budget limits as the data
// limit, its libraries' and threads' own included; 0 where that is not known. Estimates of work still
// to come add to it.
std::uint64_t dataBytesInUse();

// "1.5 GiB", "640 MiB".
std::string formatBytes(std::uint64_t bytes);

// Parses "8G", "512M", "1.5GiB", "2000000000" (bytes); nullopt for anything else.
std::optional<std::uint64_t> parseByteSize(const std::string& text);

// The message for a std::bad_alloc caught at the top of a command.
std::string outOfMemoryMessage();

}  // namespace rodfab::common
