// Findings of `inspect`, located in the job ("JOB: ENTRY: message"), at most Findings::kMaxDefects of them
// kept and the rest counted.
#include "printer_profiles/inspect_layout.hpp"

#include "printer_profiles/job_reader.hpp"

namespace rodfab::printer_profiles {

void Findings::push(std::string text) {
  if (list_.size() < kMaxDefects) list_.push_back(std::move(text));
  else ++dropped_;
}

void Findings::at(const std::string& entry, const std::string& message) {
  push(job_ + ": " + printableName(entry) + ": " + message);
}

void Findings::whole(const std::string& message) { push(job_ + ": " + message); }

void Findings::located(const std::string& message) { push(message); }

void Findings::merge(const Findings& other) {
  for (const std::string& s : other.list_) push(s);
  dropped_ += other.dropped_;
}

std::vector<std::string> Findings::take() {
  std::vector<std::string> out = std::move(list_);
  if (dropped_) out.push_back(job_ + ": ... and " + std::to_string(dropped_) + " more defects");
  list_.clear();
  dropped_ = 0;
  return out;
}

}  // namespace rodfab::printer_profiles
