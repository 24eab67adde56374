// Writing output files without ever losing data.
//
// Every file rodfab writes goes to a hidden temporary beside its final name
// (`.NAME.rodfab-tmp-PID-N`), registered for removal on interrupt (common/interrupt.hpp), and is
// renamed into place only when complete. What may be replaced is decided before any work starts
// (`checkOutputPath`): never one of the command's inputs, never a folder, and an existing file only
// when the caller says so (--force) and the file is one rodfab wrote (the `isOurs` test). The commit
// checks again: an output path created, replaced or changed since checkOutputPath looked at it (a
// person's file, saved there during a long solve) is left as it is and the commit throws.
//
// Errors are std::runtime_error whose message starts with the path concerned. Thread safety: the
// functions are reentrant; two writers to the same final name race as rename(2) does (last wins).
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rodfab::common {

// What a command may do with an existing file at its output path.
struct OutputPolicy {
  std::string what;                    // what the output is, for messages ("calibration file")
  bool replaceExisting = false;        // may an existing file be replaced at all (--force, or the command's rule)
  std::string howToReplace = "--force";  // the option that allows it, for the message
  // Recognizes a file this program wrote (bounded read; must not follow symlinks to devices).
  // Empty: any regular file may be replaced when replaceExisting is set.
  std::function<bool(const std::filesystem::path&)> isOurs;
};

// Throws std::runtime_error naming `output` when writing there could lose data: it is (the same file
// as) one of `inputs`, a folder, a symlink, something other than a regular file, an existing file
// that the policy does not let us replace, or its folder does not exist.
// Also when the name is too long for the hidden names rodfab writes beside it (checkOutputNameLength).
void checkOutputPath(const std::filesystem::path& output, const std::vector<std::filesystem::path>& inputs,
                     const OutputPolicy& policy);

// The copies `.NAME.rodfab-old-PID-N` of `output` that a run killed outright (SIGKILL, power loss: its
// CommandOutputs never settled them) left beside it: the files or jobs that run had replaced, the
// user's earlier data, returned (sorted) for the caller to report and never removed. A copy that is
// still the same file as `output` (the run was killed before its commit's rename) is only a second
// link: it is removed. Copies of live processes are skipped. Never throws.
std::vector<std::filesystem::path> leftoverPreviousVersions(const std::filesystem::path& output);

// The most bytes rodfab adds to an output's name for the hidden files it keeps beside it
// (`.NAME.rodfab-tmp-PID-N`, `.NAME.rodfab-old-PID-N`, a job's `.NAME.rodfab-partial-PID-N`): the
// leading '.', the longest tag (".rodfab-partial-", 16 bytes), a process id (at most 7 digits: Linux's
// pid_max is at most 4194304), '-' and a counter (at most 10 digits).
inline constexpr std::size_t kHiddenNameExtraBytes = 1 + 16 + 7 + 1 + 10;

// Throws std::runtime_error naming `output` when its file name plus kHiddenNameExtraBytes is longer
// than its folder's file system allows (NAME_MAX, usually 255 bytes), or the path so extended longer
// than PATH_MAX: the hidden temporary could not be made, and that would be found only when the work
// is done. The folder must exist. Called by checkOutputPath and by the job writer's checkJobOutput.
void checkOutputNameLength(const std::filesystem::path& output);

// True when the first bytes of the regular file `file` (not a symlink) start with `prefix` and, when
// `marker` is not empty, the first `scanBytes` bytes contain `marker`. False for anything unreadable.
bool fileStartsWith(const std::filesystem::path& file, std::string_view prefix, std::string_view marker = {},
                    std::size_t scanBytes = 4096);

// Files that say rodfab wrote them and that nobody has changed them since: how an `isOurs` test tells
// a file rodfab wrote from one a person wrote or edited, even one that began as rodfab's. A JSON
// object is sealed by its first member, "written_by": "rodfab, xxh128 HEX", where HEX is the XXH3-128
// of every byte after that member's line; readers take the member as an ordinary string.
inline constexpr const char* kWrittenByKey = "written_by";

// "{", a newline, the seal's line, then `members`: the object's text after its opening line, its
// closing brace included.
std::string sealJsonObject(std::string_view members);

// The whole of the regular file `file` when it is at most `maxBytes` long; nullopt for anything else
// (a link is not followed, a pipe not waited on) or when reading fails.
std::optional<std::string> readRegularFileAtMost(const std::filesystem::path& file, std::size_t maxBytes);

// True when the regular file `file` (not a symlink; at most `maxBytes` long, else false) is a sealed
// JSON object whose bytes after the seal's line are the ones sealed. False for anything unreadable.
bool isSealedJsonObject(const std::filesystem::path& file, std::size_t maxBytes = std::size_t{256} << 20);

// Flushes what was written to `path` to its device before a name is given to it, so that a crash or
// power loss never leaves a name pointing at lost data: a regular file's data (fsync), or for a folder
// the whole file system it is on (syncfs: one flush for thousands of files). A file system that
// cannot sync (EINVAL, EROFS) passes; an I/O error throws std::runtime_error naming `path`.
void syncToDevice(const std::filesystem::path& path);
// Starts writing a regular file's data to its device without waiting (sync_file_range), so that a
// syncToDevice later, after other work, finds less to write. Only a hint: a file that cannot be
// opened or a file system without it changes nothing, and nothing is promised until syncToDevice.
void startWriteback(const std::filesystem::path& file) noexcept;
// Flushes a folder's entries (the names a rename gave) after the rename, so that the new name
// survives a power loss; false when that failed (the rename itself stands either way).
bool syncFolderEntries(const std::filesystem::path& folder);

// A temporary beside `final` that becomes `final` on commit(); removed by the destructor (or on
// interrupt) if never committed. commit() throws Interrupted when a signal is pending (the
// temporary is then removed). While a common::CommandOutputs lives (common/interrupt.hpp: main holds
// one; a library user holds one around its work), the committed file stays registered until it ends
// and the file it replaced is kept beside it (`.NAME.rodfab-old-PID-N`) until then: removed on
// success, put back on failure or interrupt. Without one, commit() replaces outright and keeps nothing.
class AtomicOutput {
public:
  explicit AtomicOutput(std::filesystem::path final);
  ~AtomicOutput();
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;

  const std::filesystem::path& temporary() const { return temporary_; }
  const std::filesystem::path& final() const { return final_; }
  // Throws std::runtime_error (the temporary is then removed by the destructor) when `final` was
  // checked by checkOutputPath and is no longer as found there, and Interrupted on a pending signal.
  void commit();

private:
  std::filesystem::path final_, temporary_;
  bool committed_ = false;
};

// Writes `bytes` to `file` through an AtomicOutput (fsync before rename).
void writeFileAtomically(const std::filesystem::path& file, std::string_view bytes);

}  // namespace rodfab::common
