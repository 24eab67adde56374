// The previews' top view (Previews::addTopLayers): after each band, the band's layers from the top down
// decide the view's pixels their columns show, with the moduli of those voxels. Apart from the other
// views (previews.cpp) because it runs per band, not per layer, and reads the band's bitmaps by row blocks.
#include "printer_profiles/previews.hpp"

#include "printer_profiles/preview_scan.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <optional>
#include <vector>

namespace rodfab::printer_profiles {

using preview_scan::kNoModulus;

namespace {

// A top-view pixel a layer claims, and the modulus of its voxel (kNoModulus until looked up).
struct TopPixel {
  int column = 0;
  bool rigid = false;
  float modulus = kNoModulus;
  const openvdb::FloatTree::LeafNodeType* leaf = nullptr;
  openvdb::Index offset = 0;
};

// The moduli of `row`'s `pixels` in `layer`, as modulusAt gives them, in two passes: every pixel's leaf
// first, prefetching its value, then the values. The band's modulus grid is far out of cache, and a
// solid part's every band claims every top pixel again: one look-up after another, each waited for its
// cache miss (72 % of addTopLayers' samples on the dense block); side by side, the misses overlap.
void lookUpModuli(const openvdb::FloatGrid* grid, openvdb::FloatGrid::ConstAccessor& acc, std::vector<TopPixel>& pixels,
                  const JobGeometry& g, int row, int layer) {
  using Leaf = openvdb::FloatTree::LeafNodeType;
  for (TopPixel& p : pixels) {
    const openvdb::Coord ijk(g.i(p.column), g.j(row), g.k(layer));
    p.leaf = acc.probeConstLeaf(ijk);
    if (!p.leaf) continue;
    p.offset = Leaf::coordToOffset(ijk);
    __builtin_prefetch(p.leaf->buffer().data() + p.offset);
  }
  for (TopPixel& p : pixels) {
    if (!p.leaf) p.modulus = preview_scan::modulusAt(grid, &acc, {g.i(p.column), g.j(row), g.k(layer)});  // a tile or background
    else p.modulus = p.leaf->isValueOn(p.offset) ? p.leaf->getValue(p.offset) : kNoModulus;
  }
}

}  // namespace

void Previews::addTopLayers(int first, const std::vector<LayerBitmaps>& layers, const openvdb::FloatGrid* modulus) {
  if (modulus) haveModulus_ = true;
  if (layers.empty()) return;
  // By blocks of rows, each block read layer by layer: consecutive rows of one bitmap at a time. Row by
  // row through every layer's bitmap in turn (the band's no longer in cache) cost a cache and TLB miss
  // per row and layer.
  constexpr int kRowBlock = 32;
  const std::vector<std::uint8_t>& hidden = top_.u.hiddenMask();
  tbb::parallel_for(tbb::blocked_range<int>(0, geometry_.height, kRowBlock), [&](const tbb::blocked_range<int>& rows) {
    std::optional<openvdb::FloatGrid::ConstAccessor> acc;
    if (modulus) acc.emplace(modulus->getConstAccessor());
    // Layers from the band's top down: the first one seen in a column is its top within the band, and
    // replaces what earlier bands left (their layers are below `first`). `claimed` marks, row by row,
    // the columns a higher layer of this band already took, and those no pixel shows.
    std::vector<std::uint8_t> claimed;
    for (int r = rows.begin(); r != rows.end(); ++r) claimed.insert(claimed.end(), hidden.begin(), hidden.end());
    std::vector<TopPixel> fresh;
    for (std::size_t n = layers.size(); n-- > 0;) {
      const int layer = first + static_cast<int>(n);
      for (int r = rows.begin(); r != rows.end(); ++r) {
        if (top_.v.slot(r) < 0) continue;  // no pixel shows the row (one nothing was written in has no marked word to scan)
        std::uint8_t* rowClaimed = claimed.data() + static_cast<std::size_t>(r - rows.begin()) * hidden.size();
        if (!modulus) {  // each pixel set as it is found
          const std::size_t rowAt = top_.rowAt(r);
          preview_scan::forEachFreshInRow(layers[n], r, rowClaimed, [&](int c, bool isRigid) {
            top_.set(rowAt + static_cast<std::size_t>(top_.u.slot(c)), isRigid, layer, kNoModulus);
          });
          continue;
        }
        fresh.clear();
        preview_scan::forEachFreshInRow(layers[n], r, rowClaimed, [&](int c, bool isRigid) { fresh.push_back({c, isRigid}); });
        lookUpModuli(modulus, *acc, fresh, geometry_, r, layer);
        for (const TopPixel& p : fresh) top_.set(top_.at(p.column, r), p.rigid, layer, p.modulus);
      }
    }
  });
}

}  // namespace rodfab::printer_profiles
