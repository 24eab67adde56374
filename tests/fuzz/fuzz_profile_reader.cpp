// libFuzzer target: the printer-profile reader must answer every input with a profile or a
// ProfileError, never crash, hang or throw anything else; a profile it accepts must keep the documented
// invariants and be safe to query (materials by role, layer file names).
#include "printer_profiles/profile.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  namespace pp = rodfab::printer_profiles;
  pp::Profile profile;
  try {
    profile = pp::parseProfile(text, "fuzz.json");
  } catch (const pp::ProfileError&) {
    return 0;
  }
  if (profile.xDpi <= 0 || profile.yDpi <= 0 || profile.materials.size() != 3) std::abort();
  if (profile.columnAlignment <= 0 || profile.columnAlignment % 8 != 0) std::abort();
  if (profile.layerDigits < 1 || profile.layerDigits > 9) std::abort();
  if (!(profile.voxelVolumeMm3() > 0.0) || !(profile.layerThicknessMm() > 0.0)) std::abort();
  // Within the stated maxima: portable names, and a tray whose images fit them.
  if (!pp::portableNameProblem(profile.buildFileName).empty()) std::abort();
  for (const pp::ProfileMaterial& m : profile.materials)
    if (!pp::portableNameProblem(m.name).empty()) std::abort();
  for (int a = 0; a < 3; ++a)
    if (!(profile.trayMm[a] / profile.voxelSizeMm[a] < pp::kMaxTrayVoxels + 1.0)) std::abort();
  for (int a = 0; a < 2; ++a)
    if (2.0 * profile.paddingVoxels[a] + 1.0 > std::floor(profile.trayMm[a] / profile.voxelSizeMm[a])) std::abort();
  for (const auto role : {pp::MaterialRole::Rigid, pp::MaterialRole::Rubbery, pp::MaterialRole::Support}) {
    const pp::ProfileMaterial& material = profile.material(role);  // exactly one per role once accepted
    if (material.name.empty() || material.role != role) std::abort();
    for (const auto format : {pp::ImageFormat::Bmp, pp::ImageFormat::Png}) {
      if (profile.layerFileName(material, 0, format).empty()) std::abort();
      if (profile.layerFileName(material, 1234567890, format).empty()) std::abort();
      if (profile.layerFilePattern(material, format).empty()) std::abort();
    }
  }
  return 0;
}
