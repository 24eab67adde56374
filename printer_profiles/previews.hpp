// Internal: the previews a technician looks at before a long print. Three orthographic projections
// (top, front, right side; third-angle layout, mm to scale) coloured by material and, when the
// modulus grid is given, by modulus; and a contact sheet of evenly spaced layers. Filled layer by
// layer while the job streams, rendered at the end (cairo draws the labels, libpng writes the PNGs).
#pragma once

#include "printer_profiles/bitmap.hpp"
#include "printer_profiles/job_layout.hpp"
#include "printer_profiles/layer_bitmaps.hpp"
#include "printer_profiles/profile.hpp"

#include <openvdb/openvdb.h>

#include <bit>
#include <cassert>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::printer_profiles {

// Which cells of one axis of a view its `pixels` pixels show: pixel p shows the cell nearest its
// centre, floor((p + 0.5) * cells / pixels). A view keeps only those cells, so its memory follows the
// rendered size, not the part's (a 400 x 40 x 150 mm coupon plate held 564 MB at full resolution).
class AxisSamples {
public:
  AxisSamples() = default;
  AxisSamples(int cells, int pixels);
  int kept() const { return kept_; }                                               // cells some pixel shows
  int slot(int cell) const { return slots_[static_cast<std::size_t>(cell)]; }     // -1: no pixel shows it
  int pixels() const { return pixels_; }
  int cellOfPixel(int p) const;
  // Bit per cell as bitmap rows pack them (cell 0 in bit 7 of byte 0): 1 where no pixel shows the cell.
  const std::vector<std::uint8_t>& hiddenMask() const { return hidden_; }

private:
  int cells_ = 0, pixels_ = 0, kept_ = 0;
  std::vector<int> slots_;
  std::vector<std::uint8_t> hidden_;
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

  // Bytes the views and tiles hold (for tests and memory estimates).
  std::size_t memoryBytes() const;
  // What memoryBytes() reaches for a job of `geometry` once every contact tile is filled, worked out
  // without allocating anything: for memory estimates made before a job starts.
  static std::size_t heldBytesAtMost(const JobGeometry& geometry, const Profile& profile, int contactSheetLayers);

  // One projection at the resolution it is drawn: the cells its pixels show along u (its columns) and
  // v (its rows), each keeping the voxel seen there.
  struct View {
    AxisSamples u, v;  // top: (columns, rows); front: (columns, layers); side: (rows, layers)
    int width = 0, height = 0;           // cells kept: u.kept() x v.kept()
    std::vector<std::uint8_t> material;  // 0 empty, 1 rigid, 2 rubbery
    std::vector<std::int32_t> depth;     // layer (top), row (front) or column (side) of the visible voxel
    std::vector<float> modulus;          // MPa at that voxel, NaN when unknown
    View() = default;
    View(AxisSamples us, AxisSamples vs);
    // The kept cell at (u cell, v cell), which must be shown by some pixel (cellOfPixel's cells are).
    std::size_t at(int uCell, int vCell) const {
      assert(u.slot(uCell) >= 0);
      return rowAt(vCell) + static_cast<std::size_t>(u.slot(uCell));
    }
    // The first kept cell of v cell vCell's row (which some pixel must show).
    std::size_t rowAt(int vCell) const {
      assert(v.slot(vCell) >= 0);
      return static_cast<std::size_t>(v.slot(vCell)) * static_cast<std::size_t>(width);
    }
    void set(std::size_t at, bool rigid, int depthValue, float modulusValue) {
      material[at] = rigid ? 1 : 2;
      depth[at] = depthValue;
      modulus[at] = modulusValue;
    }
  };

private:
  void addFrontAndSide(int layer, const LayerBitmaps& b, const openvdb::FloatGrid* modulus);
  void addContactTile(int layer, const LayerBitmaps& b);

  JobGeometry geometry_;
  Profile profile_;
  View top_, front_, side_;
  bool haveModulus_ = false;
  std::vector<int> contactLayers_;
  int tileWidth_ = 0, tileHeight_ = 0;
  std::vector<std::vector<std::uint8_t>> tiles_;  // per contact layer: 0 empty, 1 rigid, 2 rubbery, 3 support
};

}  // namespace rodfab::printer_profiles
