// Internal to printer_profiles/: the job writer's hidden staging folder beside the target, the
// removal of dead writers' leftovers, and the commit of a finished job into place (a rename that never
// replaces, or an exchange with the rodfab job it replaces). See JobWriter in job_writer.hpp.
#pragma once

#include "printer_profiles/job_archive.hpp"

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>

namespace rodfab::printer_profiles {

// What marks a staging folder's name: ".NAME.rodfab-partial-PID-N".
inline constexpr const char* kPartialTag = ".rodfab-partial-";

// ".NAME.rodfab-partial-PID-N" for the target NAME, this process and `n`.
std::filesystem::path stagingPath(const std::filesystem::path& target, long n);
// The PID in a staging folder's name (this version's, or the names older versions left), or 0 when
// `name` is not exactly such a name.
long stagingPid(const std::string& name);
// Removes, in `folder`, the staging folders of writers that died (killed, crashed), whatever job
// they were writing: only entries named exactly like staging folders, only when their writer is gone;
// a link is never followed.
void removeDeadStaging(const std::filesystem::path& folder);
// Why `target` is not replaced: "TARGET: is DESCRIPTION; rodfab replaces only its own jobs ...".
std::string refusal(const std::filesystem::path& target, const OutputOccupant& occupant);

// Writes `data` as the file `path` (std::runtime_error naming it when it cannot: disk full, no permission).
void writeFile(const std::filesystem::path& path, std::span<const std::uint8_t> data);

// The writer's hidden folder beside the target. Created with its lock file taken (flock, so a later
// writer can tell a live writer from a dead one); removed with everything in it when the object goes,
// on every path, and on interrupts (common/interrupt.hpp).
class Staging {
public:
  explicit Staging(const std::filesystem::path& target);
  ~Staging() { remove(); }
  Staging(const Staging&) = delete;
  Staging& operator=(const Staging&) = delete;

  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path files() const { return root_ / "job"; }    // the job's files (a directory job as it will be)
  std::filesystem::path zip() const { return root_ / "job.zip"; }  // the zip job
  void remove();

private:
  [[noreturn]] void fail(const std::filesystem::path& parent, const std::string& why, bool created);
  void lock();

  std::filesystem::path root_;
  int lockFd_ = -1;
};

// A staged job renamed into place, and how to take it back.
struct Commit {
  bool replaced = false;
  std::filesystem::path oldJob;  // where the job it replaced lies now (in the staging folder)
  bool exchanged = false;
  std::uint64_t device = 0, inode = 0;  // of the new job
};

// Puts the staged job `built` at `target`: a rename that never replaces, or, for a rodfab job there
// and `force`, an exchange of the two names in one step (the old job lands in `staging`). What is at
// the target is examined again now: it may have changed while the job was written. Throws
// std::runtime_error naming the target when it was taken meanwhile.
Commit commitJob(const std::filesystem::path& built, const std::filesystem::path& target, bool force, const Staging& staging);
// Takes a committed job back: the target holds again what it held before (nothing, or the old job).
void undoCommit(const Commit& commit, const std::filesystem::path& target, const Staging& staging);

}  // namespace rodfab::printer_profiles
