// Reading a job's files, from a zip archive (libzip) or a plain directory, by their names in the job.
#pragma once

#include "printer_profiles/bitmap.hpp"

#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

enum class ArchiveFormat { Zip, Directory };
const char* toString(ArchiveFormat format);

// Raised when a job cannot be opened or one of its files cannot be read; names the job and file.
class JobReadError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

// Read access to the files of a job, by their names inside the job ('/' separated).
class JobFiles {
public:
  virtual ~JobFiles() = default;
  virtual const std::filesystem::path& path() const = 0;
  virtual ArchiveFormat format() const = 0;
  // Every file, sorted by name.
  virtual std::vector<std::string> names() const = 0;
  virtual bool contains(const std::string& name) const = 0;
  // Safe to call from several threads at once.
  virtual Bytes read(const std::string& name) const = 0;
};

// A directory is read as a directory job, anything else as a zip archive.
std::unique_ptr<JobFiles> openJobFiles(const std::filesystem::path& job);

}  // namespace rodfab::printer_profiles
