// Internal: the previews a technician looks at before a long print. Three orthographic projections
// (top, front, right side; third-angle layout, mm to scale) coloured by material and, when the
// modulus grid is given, by modulus; and a contact sheet of evenly spaced layers. Filled layer by
// layer while the job streams, rendered at the end (cairo draws the labels, libpng writes the PNGs).
#pragma once

#include "printer_profiles/bitmap.hpp"
#include "printer_profiles/job_layout.hpp"
#include "printer_profiles/profile.hpp"

#include <openvdb/openvdb.h>

#include <string>
#include <utility>
#include <vector>

namespace rodfab::printer_profiles {

// The model bitmaps of one layer (support may be empty when the printer adds it).
struct LayerBitmaps {
  Bitmap rigid, rubbery, support;
  bool hasSupport = false;
};

class Previews {
public:
  Previews(const JobGeometry& geometry, const Profile& profile, int contactSheetLayers);

  // Front and side views and the contact sheet for one layer. Safe for distinct layers at once.
  void addLayer(int layer, const LayerBitmaps& bitmaps, const openvdb::FloatGrid* modulus);
  // The top view for consecutive layers [first, first + size), called once per band in layer order.
  void addTopLayers(int first, const std::vector<LayerBitmaps>& layers, const openvdb::FloatGrid* modulus);

  // Layers on the contact sheet.
  const std::vector<int>& contactLayers() const { return contactLayers_; }
  // (file name inside the job, PNG bytes), in a fixed order.
  std::vector<std::pair<std::string, Bytes>> render(const std::string& title) const;

private:
  struct View {
    int width = 0, height = 0;  // in voxels: (columns, rows) of top, (columns, layers) front, (rows, layers) side
    std::vector<std::uint8_t> material;  // 0 empty, 1 rigid, 2 rubbery
    std::vector<std::int32_t> depth;     // layer (top), row (front) or column (side) of the visible voxel
    std::vector<float> modulus;          // MPa at that voxel, NaN when unknown
    void resize(int w, int h);
  };

  JobGeometry geometry_;
  Profile profile_;
  View top_, front_, side_;
  bool haveModulus_ = false;
  std::vector<int> contactLayers_;
  int tileWidth_ = 0, tileHeight_ = 0;
  std::vector<std::vector<std::uint8_t>> tiles_;  // per contact layer: 0 empty, 1 rigid, 2 rubbery, 3 support
};

}  // namespace rodfab::printer_profiles
