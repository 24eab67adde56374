// Reading a GrabCAD Voxel Print job back (inspect's part for profiles with output format "gcvf"): layer
// images decoded to one bitmap per material by colour, and ConfigFile.xml parsed (libxml2, no network,
// no DTD loading, no entity substitution) and checked against the profile and the decoded images.
#pragma once

#include "printer_profiles/bitmap.hpp"
#include "printer_profiles/job_writer.hpp"
#include "printer_profiles/profile.hpp"

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

struct GcvfLayerImage {
  std::vector<Bitmap> bitmaps;  // one per material asked for, in that order: set where the pixel is its RGBA
  std::uint32_t xPixelsPerMetre = 0, yPixelsPerMetre = 0;
  std::uint64_t foreignPixels = 0;  // pixels whose colour is neither the background nor a material's
  std::array<unsigned char, 4> firstForeign{};
  int firstForeignColumn = -1, firstForeignRow = -1;
};

// Decodes one layer image of a gcvf job that must be width x height pixels. Throws ImageError for a file
// that is not an 8-bit RGBA PNG of that size (or is damaged). Memory: the bitmaps and one row.
GcvfLayerImage decodeGcvfLayer(std::span<const std::uint8_t> png, const Profile& profile,
                               const std::vector<const ProfileMaterial*>& materials, int width, int height);

// Every problem of ConfigFile.xml (`xml`, at most a few KB from a job) against the profile, the job's
// image size and layer count, and `counted` (the job's materials in order, with the voxels decoded from
// the images): not well-formed, a missing, repeated or wrong element, a material not the profile's, a
// VoxelCount that is not what the images hold (checked only when `countsKnown`: every image was read;
// otherwise it must be a whole number). Each problem is one message; empty when the file is sound.
std::vector<std::string> checkGcvfConfig(std::span<const std::uint8_t> xml, const Profile& profile, int width, int height,
                                         int layers, const std::vector<MaterialTotals>& counted, bool countsKnown = true);

}  // namespace rodfab::printer_profiles
