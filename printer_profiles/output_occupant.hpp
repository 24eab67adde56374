// What lies at a job's output path: nothing, a rodfab job (which `--force` may replace) or anything
// else (never replaced), told apart without following links or trusting the entry's contents.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace rodfab::printer_profiles {

// What lies at a job's output path, found without following a symbolic link, without waiting on a
// pipe or device; a job's manifest is read up to kMaxManifestBytes (job_archive.hpp), each of its
// files up to the length the manifest records.
struct OutputOccupant {
  enum class Kind {
    Nothing,    // no entry of that name
    RodfabJob,  // a zip whose first entry is a manifest.json of format kJobFormat and whose other entries
                // are all files its "files" table lists, or a folder holding such a manifest and nothing
                // but regular files that table lists (previews/ too); every file of the length and
                // checksum its row records (read whole: inflated and hashed, on the caller's TBB arena)
    Other,      // anything else: a user's file or folder, a link, a foreign zip, a job with added or
                // changed files
  };
  Kind kind = Kind::Nothing;
  std::string description;              // what it is, for messages: "a folder holding notes.txt, which ..."
  std::uint64_t device = 0, inode = 0;  // of the entry itself (not a link's target)
};
// Never throws for what it finds (an unreadable entry is Other, described with the error); throws
// common::Interrupted when a signal arrives while a job's files are read.
OutputOccupant examineOutput(const std::filesystem::path& path);

}  // namespace rodfab::printer_profiles
