#include "voxel/rasterize.hpp"

#include "voxel/leaf_builder.hpp"
#include "voxel/rod_pieces.hpp"
#include "voxel/tree_assembly.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <limits>
#include <map>
#include <memory>
#include <utility>
#include <vector>

namespace rodfab::voxel {

using namespace detail;  // the block layout (raster_clips.hpp), the pieces and the LeafBuilder

namespace {

// A piece reaching a block. Sorted by (block, rod, piece), a total order: every voxel sees its pieces
// in the same order whatever the thread count or band.
struct Entry {
  std::uint64_t block;
  std::uint32_t rod, piece;
  bool operator<(const Entry& o) const {
    if (block != o.block) return block < o.block;
    if (rod != o.rod) return rod < o.rod;
    return piece < o.piece;
  }
};

// Block coordinates packed into one sort key, z-major, so the blocks of a band of layers are contiguous.
std::uint64_t packBlock(int bi, int bj, int bk) {
  return (std::uint64_t(bk) << (2 * kPackedAxisBits)) | (std::uint64_t(bj) << kPackedAxisBits) | std::uint64_t(bi);
}
openvdb::Coord blockOrigin(std::uint64_t packed) {
  const std::uint64_t mask = (std::uint64_t(1) << kPackedAxisBits) - 1;
  return openvdb::Coord(int(packed & mask) << kBlockXLog2, int((packed >> kPackedAxisBits) & mask) << kLeafLog2,
                        int(packed >> (2 * kPackedAxisBits)) << kLeafLog2);
}

// The pieces reaching each block of a band: entries sorted (see Entry), those of block g from
// start[g] to start[g + 1].
struct BlockList {
  std::vector<Entry> entries;
  std::vector<std::size_t> start;
  std::size_t count() const { return start.size() - 1; }
};

// The block coordinates (i, j, k) of the entries of a band, as ranges: a block's dense index in them
// orders blocks as their packed keys do (z-major).
struct BlockRange {
  int lo[3] = {std::numeric_limits<int>::max(), std::numeric_limits<int>::max(), std::numeric_limits<int>::max()};
  int hi[3] = {-1, -1, -1};
  void include(int i, int j, int k) {
    const int c[3] = {i, j, k};
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], c[a]), hi[a] = std::max(hi[a], c[a]);
  }
  void include(const BlockRange& o) {
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], o.lo[a]), hi[a] = std::max(hi[a], o.hi[a]);
  }
  std::uint64_t extent(int a) const { return hi[a] >= lo[a] ? std::uint64_t(hi[a] - lo[a] + 1) : 0; }
  std::uint64_t size() const { return extent(0) * extent(1) * extent(2); }
  std::uint64_t dense(std::uint64_t packed) const {
    const std::uint64_t mask = (std::uint64_t(1) << kPackedAxisBits) - 1;
    const std::uint64_t i = (packed & mask) - std::uint64_t(lo[0]), j = ((packed >> kPackedAxisBits) & mask) - std::uint64_t(lo[1]);
    const std::uint64_t k = (packed >> (2 * kPackedAxisBits)) - std::uint64_t(lo[2]);
    return (k * extent(1) + j) * extent(0) + i;
  }
};

// The per-rod entries (each in (rod, piece) order, rods in order) sorted into `list`. Stably by block
// alone, which gives the (block, rod, piece) order: a counting sort over the band's blocks (two linear
// passes; the comparison sort of the same entries cost 5 % of the curved lattice's rasterization),
// or the comparison sort where the blocks' range is far larger than the entries (a sparse band).
void sortEntries(std::vector<std::vector<Entry>>& perRod, const BlockRange& range, BlockList& list) {
  std::size_t total = 0;
  for (const auto& v : perRod) total += v.size();
  list.entries.resize(total);
  if (range.size() > 4 * std::uint64_t(total) + 4096) {
    std::size_t at = 0;
    for (auto& v : perRod) {
      std::copy(v.begin(), v.end(), list.entries.begin() + std::ptrdiff_t(at));
      at += v.size();
      std::vector<Entry>().swap(v);
    }
    tbb::parallel_sort(list.entries.begin(), list.entries.end());
    for (std::size_t e = 0; e < list.entries.size(); ++e)
      if (e == 0 || list.entries[e].block != list.entries[e - 1].block) list.start.push_back(e);
    list.start.push_back(list.entries.size());
    return;
  }
  std::vector<std::size_t> next(range.size() + 1, 0);  // entries per block, then where the next one goes
  for (const auto& v : perRod)
    for (const Entry& e : v) ++next[range.dense(e.block) + 1];
  for (std::size_t d = 0; d + 1 < next.size(); ++d) {
    if (next[d + 1] > 0) list.start.push_back(next[d]);
    next[d + 1] += next[d];
  }
  list.start.push_back(total);
  for (auto& v : perRod) {
    for (const Entry& e : v) list.entries[next[range.dense(e.block)]++] = e;
    std::vector<Entry>().swap(v);
  }
}

// Which pieces reach which blocks within layers zBegin <= k < zEnd; `poll` throws on an interrupt.
template <typename Poll>
BlockList listBlocks(const std::vector<RodPieces>& rods, int zBegin, int zEnd, const Poll& poll) {
  std::vector<std::vector<Entry>> perRod(rods.size());
  std::vector<BlockRange> ranges(rods.size());
  tbb::parallel_for(std::size_t(0), rods.size(), [&](std::size_t r) {
    const RodPieces& rod = rods[r];
    if (rod.box.empty() || rod.box.max().z() < zBegin || rod.box.min().z() >= zEnd) return;
    for (std::size_t p = 0; p < rod.pieces.size(); ++p) {
      if (p % 1024 == 0) poll();
      openvdb::CoordBBox b = rod.pieces[p].box;
      b.min().z() = std::max(b.min().z(), zBegin);
      b.max().z() = std::min(b.max().z(), zEnd - 1);
      if (b.empty()) continue;
      ranges[r].include(b.min().x() >> kBlockXLog2, b.min().y() >> kLeafLog2, b.min().z() >> kLeafLog2);
      ranges[r].include(b.max().x() >> kBlockXLog2, b.max().y() >> kLeafLog2, b.max().z() >> kLeafLog2);
      for (int k = b.min().z() >> kLeafLog2; k <= b.max().z() >> kLeafLog2; ++k)
        for (int j = b.min().y() >> kLeafLog2; j <= b.max().y() >> kLeafLog2; ++j)
          for (int i = b.min().x() >> kBlockXLog2; i <= b.max().x() >> kBlockXLog2; ++i)
            perRod[r].push_back({packBlock(i, j, k), std::uint32_t(r), std::uint32_t(p)});
    }
  });
  BlockRange range;
  for (const BlockRange& r : ranges) range.include(r);
  poll();
  BlockList list;
  sortEntries(perRod, range, list);
  poll();
  return list;
}

// Block g of the list, its pieces added in sorted order within the band, into `leaves` (none where
// no piece reaches a voxel of the band; see LeafBuilder::emit for the spares).
template <typename Poll>
void buildBlock(LeafBuilder& builder, const std::vector<RodPieces>& rods, const BlockList& list, std::size_t g, int zBegin,
                int zEnd, const Poll& poll, SpareNodes<openvdb::FloatTree>& spares, std::atomic<std::size_t>& nextSpare,
                BlockLeaves& leaves) {
  const openvdb::Coord origin = blockOrigin(list.entries[list.start[g]].block);
  openvdb::CoordBBox blockBox(origin, origin + openvdb::Coord((kLeafDim << kBlockLeavesLog2) - 1, kLeafDim - 1, kLeafDim - 1));
  blockBox.min().z() = std::max(blockBox.min().z(), zBegin);
  blockBox.max().z() = std::min(blockBox.max().z(), zEnd - 1);
  builder.clear();
  bool touched = false;
  for (std::size_t e = list.start[g]; e < list.start[g + 1]; ++e) {
    if ((e - list.start[g]) % 8 == 7) poll();
    const Entry& entry = list.entries[e];
    openvdb::CoordBBox b = rods[entry.rod].pieces[entry.piece].box;
    b.intersect(blockBox);
    if (b.empty()) continue;
    builder.addPiece(int(entry.rod), int(entry.piece), b);
    touched = true;
  }
  if (!touched) return;
  builder.emit(origin, spares, nextSpare, leaves);
}

// The blocks' leaves in a tree (background 0) from `recycler` with internal nodes from `spares`,
// grouped by leaf parent (a block, 64 voxels along x from a multiple of 64, lies in one parent): see
// tree_assembly.hpp.
openvdb::FloatTree::Ptr assembleBlocks(const BlockList& list, std::vector<BlockLeaves>& leaves,
                                       const TreeRecycler<openvdb::FloatTree>& recycler, SpareNodes<openvdb::FloatTree>& spares) {
  constexpr int kParentLog2 = LeafParentOf<openvdb::FloatTree>::TOTAL;
  std::vector<std::pair<std::uint64_t, std::size_t>> byParent;  // (parent's packed key, block), sorted
  byParent.reserve(list.count());
  for (std::size_t g = 0; g < list.count(); ++g) {
    const openvdb::Coord o = blockOrigin(list.entries[list.start[g]].block);
    byParent.emplace_back(packBlock(o.x() >> kParentLog2, o.y() >> kParentLog2, o.z() >> kParentLog2), g);
  }
  std::sort(byParent.begin(), byParent.end());
  std::vector<std::size_t> groupStart;
  for (std::size_t b = 0; b < byParent.size(); ++b)
    if (b == 0 || byParent[b].first != byParent[b - 1].first) groupStart.push_back(b);
  groupStart.push_back(byParent.size());
  const auto forEachLeaf = [&](std::size_t p, const auto& visit) {
    for (std::size_t b = groupStart[p]; b != groupStart[p + 1]; ++b)
      for (std::unique_ptr<LeafT>& leaf : leaves[byParent[b].second]) visit(leaf);
  };
  return recycler.assemble(groupStart.size() - 1, forEachLeaf, spares);
}

// A modulus grid (kModulusGridName) of `tree` on the printer's grid.
openvdb::FloatGrid::Ptr modulusGrid(openvdb::FloatTree::Ptr tree, const PrinterGrid& grid) {
  openvdb::FloatGrid::Ptr out = openvdb::FloatGrid::create(std::move(tree));
  out->setName(kModulusGridName);
  out->setTransform(grid.transform());
  out->setGridClass(openvdb::GRID_UNKNOWN);
  return out;
}

// The numbers that define a rod's solid (rod.hpp): its centerline, section, frame (reference normal or
// orientation spline) and caps, each list after its length; not its name or modulus.
std::vector<double> solidKey(const geometry::Rod& rod) {
  std::vector<double> key;
  const auto list = [&key](const auto& values, auto&& each) {
    key.push_back(static_cast<double>(values.size()));
    for (const auto& v : values) each(v);
  };
  const auto number = [&key](double v) { key.push_back(v); };
  const auto point = [&key](const geometry::Vec3& p) { key.insert(key.end(), {p.x(), p.y(), p.z()}); };
  const geometry::NurbsCurve& c = rod.centerline();
  number(c.degree());
  list(c.knots(), number);
  list(c.points(), point);
  list(c.weights(), number);
  const geometry::Section& section = rod.section();
  key.insert(key.end(), {static_cast<double>(section.shape), section.width, section.height, static_cast<double>(rod.caps())});
  number(rod.referenceNormal() ? 1 : 0);
  if (rod.referenceNormal()) point(*rod.referenceNormal());
  number(rod.orientation() ? 1 : 0);
  if (const auto& q = rod.orientation()) {
    number(q->degree());
    list(q->knots(), number);
    list(q->quaternions(), [&key](const Eigen::Vector4d& v) { key.insert(key.end(), {v[0], v[1], v[2], v[3]}); });
  }
  return key;
}

// For each rod, whether its solid is exactly an earlier rod's (a design listing a rod twice). Such a
// rod owns no voxel: the deepest rod wins an overlap and the lower index a tie, and there every voxel
// ties. Left unprepared, it costs nothing; prepared, every voxel of it went to the exact test, as a tie
// is only settled there (49 ms a copy of a 20 mm rod; a design of 2,000 copies took 100 s).
std::vector<bool> repeatsEarlierSolid(const geometry::RodStructure& structure) {
  std::map<std::vector<double>, std::size_t> first;
  std::vector<bool> repeats(structure.rods.size(), false);
  for (std::size_t r = 0; r < structure.rods.size(); ++r) repeats[r] = !first.emplace(solidKey(structure.rods[r]), r).second;
  return repeats;
}

}  // namespace

Rasterizer::Rasterizer(const geometry::RodStructure& structure, const PrinterGrid& grid, RasterOptions options)
    : structure_(&structure), grid_(grid), options_(std::move(options)), trees_(std::make_unique<TreeRecycler<openvdb::FloatTree>>(0.0f)) {
  rods_.resize(structure.rods.size());
  // Voxels are only ever emitted inside the design's bounding box (geometry::Rod::bounds holds every
  // rod's solid), the part bounds the job writer checks.
  const geometry::Box3 bounds = structure.bounds();
  partBounds_ = bounds.isEmpty() ? openvdb::CoordBBox()
                                 : grid_.voxelsWithin({bounds.min().x(), bounds.min().y(), bounds.min().z()},
                                                      {bounds.max().x(), bounds.max().y(), bounds.max().z()});
  const std::vector<bool> repeats = repeatsEarlierSolid(structure);
  tbb::task_arena arena(options_.threads > 0 ? options_.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(std::size_t(0), rods_.size(), [&](std::size_t r) {
      if (repeats[r]) return;  // no pieces: it wins no voxel anyway
      detail::RodPieces pieces = detail::buildRodPieces(structure.rods[r], grid_, options_.wasInterrupted);
      pieces.box = openvdb::CoordBBox();
      for (RodPiece& p : pieces.pieces) {
        p.box.intersect(partBounds_);
        if (!p.box.empty()) pieces.box.expand(p.box);
      }
      rods_[r] = std::move(pieces);
    });
  });
}

void Rasterizer::checkInterrupt() const {
  if (options_.wasInterrupted && options_.wasInterrupted()) throw Interrupted("rasterizer: interrupted");
}

Rasterizer::~Rasterizer() = default;
Rasterizer::Rasterizer(Rasterizer&&) noexcept = default;
Rasterizer& Rasterizer::operator=(Rasterizer&&) noexcept = default;

void Rasterizer::releaseSpareTrees() const { trees_->releaseKept(); }

std::size_t Rasterizer::pieceCount() const {
  std::size_t n = 0;
  for (const RodPieces& r : rods_) n += r.pieces.size();
  return n;
}

// On the caller's arena when it runs no more threads than asked for (the slicer's voxelize stage has
// its own): the workers of an arena made here are not the caller's arena's, whose observers (the
// pipeline's per-stage CPU time, slicer/job_pipeline.cpp) would miss their work. Either way isolated
// as an arena of its own would be: in a task group context of its own (a caller's cancelled context, a
// pipeline stopping, never skips one of the loops and returns a band short of voxels), and a thread
// waiting in it takes none of the caller's other tasks (this_task_arena::isolate).
Rasterization Rasterizer::rasterizeLayers(int zBegin, int zEnd) const {
  Rasterization out;
  const auto work = [&] { outsideCancellation([&] { tbb::this_task_arena::isolate([&] { out = run(zBegin, zEnd); }); }); };
  if (options_.threads <= 0 || options_.threads >= tbb::this_task_arena::max_concurrency()) {
    work();
  } else {
    tbb::task_arena arena(options_.threads);
    arena.execute(work);
  }
  return out;
}

Rasterization Rasterizer::run(int zBegin, int zEnd) const {
  Rasterization out;
  out.voxelsPerRod.assign(rods_.size(), 0);
  zBegin = std::max(zBegin, 0);
  zEnd = std::min(zEnd, grid_.dims.z());
  if (zBegin >= zEnd) {
    out.grid = modulusGrid(std::make_shared<openvdb::FloatTree>(0.0f), grid_);
    return out;
  }

  const auto poll = [this] { checkInterrupt(); };
  const BlockList blocks = listBlocks(rods_, zBegin, zEnd, poll);
  // Each block built by one task from its pieces, in sorted order.
  struct ThreadState {
    std::unique_ptr<LeafBuilder> builder;
  };
  tbb::enumerable_thread_specific<ThreadState> states;
  std::vector<BlockLeaves> leaves(blocks.count());
  SpareNodes<openvdb::FloatTree> spares = trees_->takeSpares();
  // The spare counter on a cache line of its own: next to `spares` (whose vectors every emit reads)
  // each count a thread took made the other thread fetch that line again.
  struct alignas(64) SpareCounter {
    std::atomic<std::size_t> next{0};
  } nextSpare;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks.count()), [&](const tbb::blocked_range<std::size_t>& range) {
    ThreadState& state = states.local();
    if (!state.builder) state.builder.reset(new LeafBuilder(*structure_, rods_, grid_, options_.wasInterrupted));  // slots mostly uninitialized
    for (std::size_t g = range.begin(); g != range.end(); ++g) {
      poll();
      buildBlock(*state.builder, rods_, blocks, g, zBegin, zEnd, poll, spares, nextSpare.next, leaves[g]);
    }
  });

  checkInterrupt();  // a builder that saw the interrupt while settling a block left it incomplete
  for (ThreadState& s : states) {
    out.exactEvaluations += s.builder->exactEvaluations;
    out.quadsSettledAtOnce += s.builder->quadsSettledAtOnce;
    for (std::size_t r = 0; r < rods_.size(); ++r) out.voxelsPerRod[r] += s.builder->voxelsPerRod[r];
  }
  out.grid = modulusGrid(assembleBlocks(blocks, leaves, *trees_, spares), grid_);
  return out;
}

Rasterization rasterize(const geometry::RodStructure& structure, const PrinterGrid& grid, RasterOptions options) {
  return Rasterizer(structure, grid, options).rasterize();
}

}  // namespace rodfab::voxel
