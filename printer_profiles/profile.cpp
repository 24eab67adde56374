// Printer profiles: names of their values, layer file names, and finding and loading profile files
// (bundled or given by path). The checks of a profile's contents are in profile_reader.cpp.
#include "printer_profiles/profile.hpp"

#include "common/data_dir.hpp"

#include <boost/algorithm/string/join.hpp>
#include <boost/range/adaptor/transformed.hpp>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace rodfab::printer_profiles {

const char* toString(MaterialRole role) {
  switch (role) {
    case MaterialRole::Rigid: return "rigid";
    case MaterialRole::Rubbery: return "rubbery";
    case MaterialRole::Support: return "support";
  }
  return "?";
}

const char* toString(ImageFormat format) { return format == ImageFormat::Bmp ? "bmp" : "png"; }

ImageFormat parseImageFormat(const std::string& text) {
  if (text == "bmp") return ImageFormat::Bmp;
  if (text == "png") return ImageFormat::Png;
  throw std::invalid_argument("image format '" + text + "' is not one of: bmp, png");
}

const char* toString(JobFormat format) { return format == JobFormat::Gcvf ? "gcvf" : "bitmap-stacks"; }

const char* toString(SupportPolicy policy) { return policy == SupportPolicy::Printer ? "printer" : "explicit"; }

SupportPolicy parseSupportPolicy(const std::string& text) {
  if (text == "printer") return SupportPolicy::Printer;
  if (text == "explicit") return SupportPolicy::Explicit;
  throw std::invalid_argument("support policy '" + text + "' is not one of: printer, explicit");
}

const ProfileMaterial& Profile::material(MaterialRole role) const {
  for (const ProfileMaterial& m : materials)
    if (m.role == role) return m;
  throw std::logic_error(std::string("profile ") + name + " has no " + toString(role) + " material");
}

std::string Profile::layerFileName(const ProfileMaterial& m, int layer, ImageFormat format) const {
  if (jobFormat == JobFormat::Gcvf) return gcvf.imageFilePrefix + std::to_string(layer) + ".png";
  std::string number = std::to_string(layer);
  if (static_cast<int>(number.size()) < layerDigits) number.insert(0, layerDigits - number.size(), '0');
  return m.name + "_" + number + "." + toString(format);
}

std::string Profile::layerFilePattern(const ProfileMaterial& m, ImageFormat format) const {
  if (jobFormat == JobFormat::Gcvf) return gcvf.imageFilePrefix + "N.png";
  return m.name + "_" + std::string(layerDigits, 'x') + "." + toString(format);
}

Profile readProfile(const std::filesystem::path& file) {
  // Non-blocking, so that a named pipe is refused instead of waited on; then only a regular file is read.
  const int fd = ::open(file.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) throw ProfileError(file.string(), {{"", std::string("cannot open the profile file (") + std::strerror(errno) + ")"}});
  struct stat st {};
  std::string text;
  std::string problem;
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    problem = "is not a regular file; expected a printer profile (JSON)";
  } else {
    // At most one byte more than allowed: enough to know the file is too large, whatever its size says.
    text.resize(kMaxProfileBytes + 1);
    std::size_t got = 0;
    while (got < text.size()) {
      const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) problem = std::string("cannot read the profile file (") + std::strerror(errno) + ")";
      if (n <= 0) break;
      got += static_cast<std::size_t>(n);
    }
    text.resize(got);
  }
  ::close(fd);
  if (!problem.empty()) throw ProfileError(file.string(), {{"", problem}});
  if (text.size() > kMaxProfileBytes)
    throw ProfileError(file.string(), {{"", "is larger than " + std::to_string(kMaxProfileBytes) +
                                                " bytes; a printer profile is a small JSON file"}});
  Profile p = parseProfile(text, file.string());
  p.source = file;
  return p;
}

std::filesystem::path bundledProfileDir() {
  return common::dataDir() / "profiles";
}

std::vector<std::string> bundledProfileNames() {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(bundledProfileDir(), ec))
    if (entry.is_regular_file() && entry.path().extension() == ".json") names.push_back(entry.path().stem().string());
  std::sort(names.begin(), names.end());
  return names;
}

Profile loadProfile(const std::string& nameOrPath) {
  const bool isName = nameOrPath.find('/') == std::string::npos && !nameOrPath.ends_with(".json");
  if (!isName) return readProfile(nameOrPath);
  // Looked up among the bundled names, not by testing the path: a name of 300 characters would make
  // the file system's "File name too long" the message.
  const std::vector<std::string> bundled = bundledProfileNames();
  if (std::find(bundled.begin(), bundled.end(), nameOrPath) == bundled.end()) {
    const std::string list = boost::algorithm::join(bundled, ", ");
    throw ProfileError(nameOrPath, {{"", "no bundled profile of that name in " + bundledProfileDir().string() +
                                             " (bundled: " + (list.empty() ? "none" : list) +
                                             "); give a path to use another profile file"}});
  }
  const std::filesystem::path file = bundledProfileDir() / (nameOrPath + ".json");
  Profile p = readProfile(file);
  if (p.name != nameOrPath)
    throw ProfileError(file.string(), {{"name", "expected \"" + nameOrPath + "\" (the file name), got \"" + p.name + "\""}});
  return p;
}

Profile withPrintMode(const Profile& profile, const std::string& mode) {
  for (const PrintMode& m : profile.printModes) {
    if (m.name == mode) {
      Profile p = profile;
      p.voxelSizeMm[2] = m.layerThicknessMm;
      p.printMode = m.name;
      return p;
    }
  }
  const std::string known = boost::algorithm::join(
      profile.printModes | boost::adaptors::transformed([](const PrintMode& m) { return m.name; }), ", ");
  throw ProfileError(profile.source.string(),
                     {{"resolution.print_modes", "no print mode \"" + mode + "\" (" +
                                                     (known.empty() ? "the " + profile.name + " profile has no print modes"
                                                                    : "modes: " + known) + ")"}});
}

}  // namespace rodfab::printer_profiles
