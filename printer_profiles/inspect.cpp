// Inspecting a job: its entries, manifest, profile, build file, previews and report (the layer images
// are checked in inspect_layers.cpp).
#include "printer_profiles/inspect.hpp"

#include "common/file_hasher.hpp"
#include "printer_profiles/inspector.hpp"
#include "printer_profiles/job_staging.hpp"  // kPartialTag

#include <boost/algorithm/string/join.hpp>
#include <boost/range/adaptor/transformed.hpp>

#include <algorithm>
#include <cctype>
#include <map>
#include <set>
#include <sstream>
#include <string_view>

namespace rodfab::printer_profiles {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr int kMaxFolderDepth = 2;  // the job and its previews/ folder; deeper folders are listed, not entered

std::string lowercase(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// `KEY = VALUE;` lines of a build file (no regular expressions: they recurse on long inputs).
std::map<std::string, std::string> buildFileValues(const std::string& text) {
  const auto trim = [](std::string s) {
    const auto first = s.find_first_not_of(" \t\r");
    if (first == std::string::npos) return std::string();
    return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
  };
  std::map<std::string, std::string> values;
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    const std::string line = text.substr(start, end - start);
    start = end + 1;
    const std::size_t eq = line.find('=');
    const std::size_t semi = line.rfind(';');
    if (eq == std::string::npos || semi == std::string::npos || semi < eq) continue;
    values.emplace(trim(line.substr(0, eq)), trim(line.substr(eq + 1, semi - eq - 1)));
  }
  return values;
}

// Reports the first few findings of one kind and counts the rest, so one kind cannot hide the others.
class Tally {
public:
  Tally(Findings& findings, std::string what) : findings_(findings), what_(std::move(what)) {}
  void at(const std::string& entry, const std::string& message) {
    if (++count_ <= kShown) findings_.at(entry, message);
  }
  void finish() {
    if (count_ > kShown) findings_.whole("and " + std::to_string(count_ - kShown) + " more " + what_);
  }

private:
  static constexpr std::size_t kShown = 8;
  Findings& findings_;
  std::string what_;
  std::size_t count_ = 0;
};

// The profiles whose limits bound what is read before the manifest names one: the caller's, or every
// bundled one.
std::vector<Profile> candidateProfiles(const InspectOptions& options) {
  if (options.profile) return {*options.profile};
  std::vector<Profile> out;
  for (const std::string& name : bundledProfileNames()) try {
      out.push_back(loadProfile(name));
    } catch (const ProfileError&) {
      // A broken bundled profile cannot vouch for any job: jobs naming it are not checked (findProfile).
    }
  return out;
}

ProfileLimits widestLimits(const std::vector<Profile>& profiles) {
  ProfileLimits w{0, 0, 0, 4096, 1u << 20, 65536};
  for (const Profile& p : profiles) {
    const ProfileLimits l = limitsOf(p);
    w.maxEntries = std::max(w.maxEntries, l.maxEntries);
    w.maxManifestBytes = std::max(w.maxManifestBytes, l.maxManifestBytes);
    w.maxManifestValues = std::max(w.maxManifestValues, l.maxManifestValues);
  }
  return w;
}

}  // namespace

namespace detail {

void Inspector::run() {
  candidates_ = candidateProfiles(options_);
  limits_ = widestLimits(candidates_);
  try {
    reader_ = openJobReader(job_, limits_.maxEntries, kMaxFolderDepth);
  } catch (const JobReadError& e) {
    findings_.located(e.what());
    return finish();
  }
  indexEntries();
  const bool profileKnown = readManifest() && resolveProfile();
  if (truncatedPastBundled_ && report_.checked()) findings_.whole(tooManyEntries());
  else if (truncatedPastBundled_)  // what lies past the listing (unsafe names, links) was not looked at either
    report_.notChecked += "; it holds more than " + std::to_string(limits_.maxEntries) +
                          " entries, more than a job of any bundled profile, and those past them were not examined";
  if (profileKnown && readJobLayout()) {
    checkEntries();
    if (!gcvf()) checkBuildFile();
    checkPreviews();
    checkReport();
    checkLayers();
    if (gcvf()) checkGcvfConfig();  // its VoxelCounts are checked against the decoded images
  }
  finish();
}

// Names every entry that no job may hold; keeps the safe, unique, regular files for reading.
void Inspector::indexEntries() {
  std::map<std::string, std::string> seen;  // lowercase name -> name as first found
  std::set<std::string> ambiguous;
  for (const JobEntry& e : reader_->entries()) {
    if (const auto why = unsafeEntryName(e.name)) {
      findings_.at(e.name, "unsafe entry name: it " + *why + "; a job's names are plain relative paths");
      reported_.insert(e.name);
      continue;
    }
    const auto [it, fresh] = seen.emplace(lowercase(e.name), e.name);
    if (!fresh) {
      findings_.at(e.name, it->second == e.name ? "appears more than once in the job"
                                                : "differs from " + printableName(it->second) +
                                                      " only in letter case: Windows and macOS would keep one of them");
      ambiguous.insert(it->second);
      reported_.insert(e.name);
      continue;
    }
    if (e.kind == EntryKind::Other) {
      findings_.at(e.name, "is " + e.otherWhat + "; a job holds only regular files and folders (it was not opened)");
      reported_.insert(e.name);
    } else if (e.kind == EntryKind::Directory) {
      folders_.insert(e.name);
    } else {
      files_[e.name] = &e;
    }
  }
  for (const std::string& name : ambiguous) {
    files_.erase(name);
    reported_.insert(name);
  }
  if (!reader_->truncated()) return;
  if (options_.profile) findings_.whole(tooManyEntries());
  else truncatedPastBundled_ = true;  // a defect unless the job's profile turns out not to be bundled (run)
}

std::string Inspector::tooManyEntries() const {
  return "holds more than " + std::to_string(limits_.maxEntries) + " entries, more than a job of " +
         (options_.profile ? "that profile" : "any bundled profile") + " can; the rest were not listed";
}

// The manifest's entry: listed, or looked up by name when the listing stopped before it (then kept as a
// listed file, or reported as indexEntries reports what no job holds). nullptr after a finding.
const JobEntry* Inspector::manifestEntry() {
  if (const auto it = files_.find(kManifestName); it != files_.end()) return it->second;
  if (reported_.count(kManifestName)) return nullptr;
  if (reader_->truncated()) unlistedManifest_ = reader_->findUnlisted(kManifestName);
  if (unlistedManifest_ && unlistedManifest_->kind == EntryKind::File) return files_[kManifestName] = &*unlistedManifest_;
  if (unlistedManifest_)
    findings_.at(kManifestName, "is " + (unlistedManifest_->kind == EntryKind::Directory ? std::string("a folder") : unlistedManifest_->otherWhat) +
                                    "; a job holds only regular files and folders (it was not opened)");
  else findings_.whole(std::string("no ") + kManifestName + ": not a finished rodfab job");
  reported_.insert(kManifestName);
  return nullptr;
}

bool Inspector::readManifest() {
  const JobEntry* entry = manifestEntry();
  if (!entry) return false;
  try {
    const Bytes text = reader_->read(*entry, limits_.maxManifestBytes);
    report_.manifest = parseUntrustedJson(text, limits_.maxManifestValues);
    return true;
  } catch (const EntryTooLarge& e) {
    if (options_.profile) findings_.located(e.what());
    else notCheckedAsTooLarge(std::to_string(limits_.maxManifestBytes) + " bytes");
  } catch (const UntrustedJsonTooLarge& e) {
    if (options_.profile) findings_.at(kManifestName, std::string("cannot be read: ") + e.what());
    else notCheckedAsTooLarge(std::to_string(limits_.maxManifestValues) + " values");
  } catch (const JobReadError& e) {
    findings_.located(e.what());
  } catch (const std::runtime_error& e) {
    findings_.at(kManifestName, std::string("cannot be read: ") + e.what());
  }
  report_.manifest = nullptr;
  return false;
}

// A manifest larger than the largest job's of the caller's profile is a defect; without one, larger
// than any bundled profile's job may be the manifest of a profile file's job with more layers (whose
// name could not be read without reading it all): the job is not checked.
void Inspector::notCheckedAsTooLarge(const std::string& most) {
  report_.notChecked = std::string("its ") + kManifestName + " holds more than " + most +
                       ", more than a job of any bundled printer profile (a job made with a profile file with more "
                       "layers?); inspect --profile FILE checks it against that profile's file";
}

// The profile comes from the caller or, by name only, from the bundled ones: never from a path.
bool Inspector::resolveProfile() {
  if (!findProfile()) return false;
  // A job made in another print mode than the profile's default (the J750's high-mix) says so.
  const json& m = report_.manifest;
  const json* mode = m["profile"].is_object() && m["profile"].contains("print_mode") ? &m["profile"]["print_mode"] : nullptr;
  if (!mode || (mode->is_string() && mode->get<std::string>() == profile_.printMode)) return true;
  try {
    if (!mode->is_string()) throw ProfileError(profile_.name, {{"", "expected the name of a print mode"}});
    profile_ = withPrintMode(profile_, mode->get<std::string>());
    return true;
  } catch (const ProfileError& e) {
    findings_.at(kManifestName, "profile.print_mode: " + printableName(e.issues().front().message));
    return false;
  }
}

bool Inspector::findProfile() {
  if (options_.profile) {
    profile_ = *options_.profile;
    return true;
  }
  const json& m = report_.manifest;
  const json* name = m.is_object() && m.contains("profile") && m["profile"].is_object() && m["profile"].contains("name")
                         ? &m["profile"]["name"]
                         : nullptr;
  if (!name || !name->is_string()) {
    findings_.at(kManifestName, "profile.name: missing; expected the name of a bundled printer profile");
    return false;
  }
  const std::string named = name->get<std::string>();
  for (const Profile& p : candidates_)
    if (p.name == named) {
      profile_ = p;
      return true;
    }
  if (const std::string problem = portableNameProblem(named); !problem.empty()) {
    findings_.at(kManifestName, "profile.name: \"" + printableName(named) + "\" cannot name any printer profile (" + problem + ")");
    return false;
  }
  // Not a defect: a job made with a profile file is checked against that file, which only the caller can name.
  const std::string bundled =
      boost::algorithm::join(candidates_ | boost::adaptors::transformed([](const Profile& p) { return p.name; }), ", ");
  const std::vector<std::string> names = bundledProfileNames();
  if (std::find(names.begin(), names.end(), named) != names.end())  // bundled, but it did not load
    report_.notChecked = "made with the bundled printer profile \"" + printableName(named) +
                         "\", which cannot be loaded here (a damaged installation?); inspect --profile FILE checks it against a copy";
  else
    report_.notChecked = "made with printer profile \"" + printableName(named) + "\", which is not bundled (bundled: " +
                         (bundled.empty() ? "none could be loaded: a damaged installation?" : bundled) +
                         "); inspect --profile FILE checks it against that profile's file";
  return false;
}

bool Inspector::readJobLayout() {
  InspectSummary& s = report_.summary;
  s.profile = profile_.name;
  s.printer = profile_.printer;
  s.xDpi = profile_.xDpi;
  s.yDpi = profile_.yDpi;
  s.layerThicknessMm = profile_.layerThicknessMm();
  s.bitDepth = profile_.imageBitDepth();
  std::optional<JobLayout> layout = readLayout(report_.manifest, profile_, findings_, s);
  if (!layout) return false;
  layout_ = std::move(*layout);
  report_.width = layout_.width;
  report_.height = layout_.height;
  report_.layers = layout_.layers;
  return true;
}

void Inspector::checkEntries() {
  std::set<std::string> parents;  // folders that hold expected entries
  for (const auto& [name, expected] : layout_.expected)
    for (std::size_t slash = name.find('/'); slash != std::string::npos; slash = name.find('/', slash + 1))
      parents.insert(name.substr(0, slash + 1));
  Tally unexpected(findings_, "unexpected entries");
  for (const std::string& folder : folders_)
    if (!parents.count(folder)) unexpected.at(folder, "unexpected folder: a job for " + profile_.name + " has none of that name");
  for (const auto& [name, entry] : files_)
    if (!layout_.expected.count(name))
      unexpected.at(name, "unexpected entry: not part of a " + std::to_string(layout_.layers) + "-layer " +
                              toString(layout_.imageFormat) + " job for " + profile_.name);
  unexpected.finish();
  reportMissing();
  Tally table(findings_, "problems in the manifest's file table");
  for (const auto& [name, expected] : layout_.expected)
    if (expected.role != EntryRole::Manifest && !layout_.listed.count(name))
      table.at(kManifestName, "files: lacks " + printableName(name) + ", which the job must hold");
  for (const auto& [name, listed] : layout_.listed)
    if (!layout_.expected.count(name)) table.at(kManifestName, "files: lists " + printableName(name) + ", which is not part of the job");
  table.finish();
}

// Missing entries; a material whose every image is missing is one finding, not one per layer.
void Inspector::reportMissing() {
  std::vector<int> missingImages(layout_.materials.size(), 0);
  for (const auto& [name, expected] : layout_.expected)
    if (expected.role == EntryRole::Layer && !files_.count(name)) ++missingImages[static_cast<std::size_t>(expected.material)];
  for (std::size_t n = 0; n < layout_.materials.size(); ++n)
    if (missingImages[n] == layout_.layers)
      findings_.whole("every " + layout_.materials[n]->name + " image is missing (" + std::to_string(layout_.layers) +
                      " layers): the job cannot print its " + toString(layout_.materials[n]->role) + " material");
  Tally missing(findings_, "missing entries");
  for (const auto& [name, expected] : layout_.expected) {
    if (files_.count(name) || reported_.count(name)) continue;
    if (expected.role == EntryRole::Layer && missingImages[static_cast<std::size_t>(expected.material)] == layout_.layers) continue;
    missing.at(name, "missing: a " + std::to_string(layout_.layers) + "-layer job for " + profile_.name + " holds it");
  }
  missing.finish();
}

// Streams an expected entry: its declared and actual size against its cap, its size and checksum
// against the manifest. Keeps at most `keep` leading bytes. nullopt after a finding.
std::optional<Bytes> Inspector::fetch(const std::string& name, std::uint64_t keep, Findings& out) const {
  const auto file = files_.find(name);
  const auto listed = layout_.listed.find(name);
  if (file == files_.end() || listed == layout_.listed.end()) return std::nullopt;  // reported by checkEntries
  const std::uint64_t cap = layout_.expected.at(name).maxBytes;
  if (file->second->declaredBytes > cap) {
    out.at(name, "declares " + std::to_string(file->second->declaredBytes) + " bytes; at most " + std::to_string(cap) +
                     " fit a " + std::to_string(layout_.width) + " x " + std::to_string(layout_.height) + " job's entry (not read)");
    return std::nullopt;
  }
  Bytes kept;
  common::FileHasher digest(listed->second.digest.algorithm);
  std::uint64_t bytes = 0;
  try {
    reader_->stream(*file->second, cap, [&](std::span<const std::uint8_t> chunk) {
      digest.update(chunk);
      bytes += chunk.size();
      const std::size_t room = static_cast<std::size_t>(std::min<std::uint64_t>(keep - kept.size(), chunk.size()));
      kept.insert(kept.end(), chunk.begin(), chunk.begin() + static_cast<std::ptrdiff_t>(room));
    });
  } catch (const JobReadError& e) {
    out.located(e.what());
    return std::nullopt;
  }
  if (bytes != listed->second.bytes || digest.hex() != listed->second.digest.hex) {
    out.at(name, "checksum mismatch (the file was changed or damaged): " + std::to_string(bytes) +
                     " bytes, the manifest says " + std::to_string(listed->second.bytes));
    return std::nullopt;
  }
  ++filesChecked_;
  return kept;
}

void Inspector::checkStored(const std::string& name, const StoredForm& want, Findings& out) const {
  const auto file = files_.find(name);
  const auto listed = layout_.listed.find(name);
  if (file == files_.end() || listed == layout_.listed.end()) return;  // reported by checkEntries
  common::FileHasher digest(common::HashAlgorithm::Xxh128);
  std::uint64_t bytes = 0;
  StoredEntryInfo directory;
  try {
    directory = reader_->streamStored(*file->second, want.storedBytes, [&](std::span<const std::uint8_t> chunk) {
      digest.update(chunk);
      bytes += chunk.size();
    });
  } catch (const JobReadError& e) {
    out.located(e.what());
    return;
  }
  if (bytes != want.storedBytes || digest.hex() != want.xxh128)
    return out.at(name, "its stored bytes are not those the writer staged (" + std::to_string(bytes) + " bytes, staged " +
                            std::to_string(want.storedBytes) + "): the file was changed or damaged");
  if (directory.deflated != want.deflated || directory.crc32 != want.crc32 || directory.size != listed->second.bytes)
    return out.at(name, "the zip's directory records another method, CRC-32 or size than the writer gave it");
  ++filesChecked_;
}

void Inspector::checkBuildFile() {
  const std::string& name = profile_.buildFileName;
  const auto data = fetch(name, UINT64_MAX, findings_);
  if (!data) return;
  const auto values = buildFileValues(std::string(data->begin(), data->end()));
  const auto expect = [&](const std::string& key, const std::string& want) {
    const auto it = values.find(key);
    if (it == values.end() || it->second != want)
      findings_.at(name, "expected '" + key + " = " + want + ";'" +
                             (it == values.end() ? std::string(", found no such line") : ", found '" + printableName(it->second) + "'"));
  };
  expect("Format version", std::to_string(profile_.buildFormatVersion));
  expect("Number of slices", std::to_string(layout_.layers));
  std::ostringstream thickness;
  thickness << profile_.layerThicknessMm();  // as the writer prints it
  expect("Layer thickness", thickness.str());
  expect("Support", profile_.material(MaterialRole::Support).name);
  for (const ProfileMaterial* m : layout_.materials) expect(m->name, profile_.layerFilePattern(*m, layout_.imageFormat));
}

// Previews are only looked at by people: their checksum and that they are 8-bit RGB PNGs suffice.
void Inspector::checkPreviews() {
  for (const auto& [name, expected] : layout_.expected) {
    if (expected.role != EntryRole::Preview && expected.role != EntryRole::ContactSheet) continue;
    const auto head = fetch(name, 26, findings_);
    if (!head) continue;
    static constexpr std::uint8_t kSignature[16] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R'};
    if (head->size() < 26 || !std::equal(kSignature, kSignature + 16, head->begin()) || (*head)[24] != 8 || (*head)[25] != 2)
      findings_.at(name, "is not an 8-bit RGB PNG image");
  }
}

// The job report (report.html) is read by people too: its checksum, and that it is an HTML page.
void Inspector::checkReport() {
  const auto it = layout_.expected.find(kReportName);
  if (it == layout_.expected.end()) return;
  const auto head = fetch(kReportName, 15, findings_);
  static constexpr std::string_view kDoctype = "<!DOCTYPE html>";
  if (head && std::string_view(reinterpret_cast<const char*>(head->data()), head->size()) != kDoctype)
    findings_.at(kReportName, "is not an HTML page (expected it to start with <!DOCTYPE html>)");
}

}  // namespace detail

InspectReport inspectJob(const fs::path& job, const InspectOptions& options) {
  InspectReport report;
  report.job = job;
  if (job.filename().string().find(kPartialTag) != std::string::npos) {
    report.defects.push_back(job.string() + ": an unfinished job (temporary name of an interrupted or running write)");
    return report;
  }
  detail::Inspector(job, options, report).run();
  return report;
}

}  // namespace rodfab::printer_profiles
