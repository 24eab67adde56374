// GrabCAD Voxel Print output (profiles with output format "gcvf", the J750/J850 family): one RGBA PNG
// per layer in which each colour is one material, and ConfigFile.xml describing the stack. The job
// writer (job_writer.hpp) stages, archives, verifies and commits these like any job; a .gcvf is the zip
// form of such a job (see printer_profiles/README.md for the layout and its public documentation).
#pragma once

#include "printer_profiles/bitmap.hpp"
#include "printer_profiles/profile.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace rodfab::printer_profiles {

// The layer image: a pixel is the rigid material's RGBA where `rigid` is set, the rubbery one's where
// `rubbery` is set, the background's elsewhere (the two never overlap: the writer makes them from one
// grid). Same size bitmaps; 8-bit RGBA PNG with the profile's dpi in pHYs. Deterministic bytes.
Bytes encodeGcvfLayer(const Bitmap& rigid, const Bitmap& rubbery, const Profile& profile);

struct GcvfMaterialCount {
  const ProfileMaterial* material = nullptr;
  std::uint64_t voxels = 0;
};

// ConfigFile.xml for a stack of `layers` images of width x height pixels: Version, Resolution (XDpi,
// YDpi, SliceThicknessNanoMeter from the profile's layer thickness), SliceDimensions, SliceRange (from
// 0), BitDepth, MaxNumberOfColors, DataSemantics Materials, CreationMode, ImageFilePrefix and the
// MaterialList (the background RGBA, then one Material per entry of `counts` with Name, RGBA and
// VoxelCount). Names are XML-escaped.
std::string gcvfConfigXml(const Profile& profile, int width, int height, int layers, const std::vector<GcvfMaterialCount>& counts);

// "R G B A" as ConfigFile.xml writes a colour.
std::string gcvfRgbaText(const std::array<unsigned char, 4>& rgba);

}  // namespace rodfab::printer_profiles
