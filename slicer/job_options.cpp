#include "slicer/job_options.hpp"

#include <stdexcept>

namespace rodfab::cli {

std::string formatCount(std::uint64_t n) {
  const std::string digits = std::to_string(n);
  std::string out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

std::optional<std::string> parseJobOptions(const po::variables_map& vm, printer_profiles::JobOptions& out) {
  out.output = vm["output"].as<std::string>();
  out.force = vm.count("force") > 0;
  const std::string format = vm["format"].as<std::string>();
  if (format == "zip") out.archive = printer_profiles::ArchiveFormat::Zip;
  else if (format == "dir") out.archive = printer_profiles::ArchiveFormat::Directory;
  else return "--format: expected zip or dir, got '" + format + "'";
  try {
    if (vm.count("image-format")) out.imageFormat = printer_profiles::parseImageFormat(vm["image-format"].as<std::string>());
    if (vm.count("support")) out.support = printer_profiles::parseSupportPolicy(vm["support"].as<std::string>());
  } catch (const std::invalid_argument& e) {
    return std::string(e.what());
  }
  return std::nullopt;
}

}  // namespace rodfab::cli
