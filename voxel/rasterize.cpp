#include "voxel/rasterize.hpp"

#include "voxel/rod_pieces.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>

namespace rodfab::voxel {

using detail::IndexForm;
using detail::RodPiece;
using detail::RodPieces;
using LeafT = openvdb::FloatTree::LeafNodeType;

namespace {

constexpr int kLeafLog2 = 3;
constexpr int kLeafDim = 1 << kLeafLog2;
constexpr int kLeafVoxels = kLeafDim * kLeafDim * kLeafDim;
// Work is binned by blocks of 4 leaves along x (32 x 8 x 8 voxels): rows along x then run up to 32
// voxels per setup instead of 8, and a block holds 48 KiB of candidates (the L2 cache's share).
constexpr int kBlockLeavesLog2 = 2;
constexpr int kBlockLeaves = 1 << kBlockLeavesLog2;
constexpr int kBlockXLog2 = kLeafLog2 + kBlockLeavesLog2;
constexpr int kBlockX = 1 << kBlockXLog2;
constexpr int kBlockVoxels = kBlockLeaves * kLeafVoxels;
constexpr int kKeyBits = 21;  // per axis in a block key: PrinterGrid caps dims at 2^24 voxels

// Within this distance (mm) beyond an end plane Rod::classify still uses the section (its own plane
// tolerance is 1e-9 (1 + bounding radius)); such voxel centres go to the exact test.
double capPlaneBand(double boundingRadius) { return 1e-7 * (1.0 + boundingRadius); }

// One rod's claim on a voxel.
// One rod's claim on a voxel: 24 bytes, so a block's slots stay in the L2 cache.
struct Candidate {
  double depth = -std::numeric_limits<double>::infinity();
  float band = 0.0f;  // |depth - exact depth| bound, rounded up; 0 when the exact test computed it
  float value = 0.0f;
  int rod = -1;       // -1: outside (the exact test found the centre outside the rod)
  int piece = -1;
  bool inside() const { return rod >= 0; }
};

// A double band as a float that is not smaller.
float bandAsFloat(double band) {
  const float f = static_cast<float>(band);
  return double(f) >= band ? f : std::nextafter(f, std::numeric_limits<float>::infinity());
}

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

// Blocks in z-major order, so a band's blocks are contiguous.
std::uint64_t blockKey(int bi, int bj, int bk) {
  return (std::uint64_t(bk) << (2 * kKeyBits)) | (std::uint64_t(bj) << kKeyBits) | std::uint64_t(bi);
}
openvdb::Coord blockOrigin(std::uint64_t key) {
  const std::uint64_t mask = (std::uint64_t(1) << kKeyBits) - 1;
  return openvdb::Coord(int(key & mask) << kBlockXLog2, int((key >> kKeyBits) & mask) << kLeafLog2,
                        int(key >> (2 * kKeyBits)) << kLeafLog2);
}

int clampToInt(double v) { return static_cast<int>(std::clamp(v, -2.0e9, 2.0e9)); }

// Voxel indices are below 2^24, so a root computed in double is off by far less than this; the
// clips keep that margin and the callers still test every voxel they are left with.
constexpr double kClipMargin = 1e-6;

// Depths closer than this are a tie (see rasterize.hpp): far below any approximation band, far above
// the round-off in a depth.
constexpr double kTieTolerance = kDepthTieTolerance;

// Restricts [lo, hi] to the i with base + slope * i >= 0 (conservatively). Returns false when
// nothing is left.
bool clipHalfLine(double base, double slope, int& lo, int& hi) {
  if (slope > 0.0) {
    lo = std::max(lo, clampToInt(std::ceil(-base / slope - kClipMargin)));
  } else if (slope < 0.0) {
    hi = std::min(hi, clampToInt(std::floor(-base / slope + kClipMargin)));
  } else if (base < 0.0) {
    return false;
  }
  return lo <= hi;
}

class LeafBuilder {
public:
  LeafBuilder(const geometry::RodStructure& structure, const std::vector<RodPieces>& rods, const PrinterGrid& grid)
      : structure_(structure), rods_(rods), grid_(grid) {}

  std::uint64_t exactEvaluations = 0;

  // Slots hold a candidate of a rod the voxel lies in exactly where their bit in `filled_` is set:
  // clearing a block costs 256 bytes, not the 48 KiB of slots.
  void clear() { filled_.fill(0); }
  // Calls f(leaf, offset in that leaf, candidate) for every filled slot, in slot order.
  template <typename F>
  void forEachFilled(F&& f) const {
    for (int w = 0; w < kWords; ++w)
      for (std::uint64_t bits = filled_[w]; bits != 0; bits &= bits - 1) {
        const int n = w * 64 + std::countr_zero(bits);
        const int x = n & (kBlockX - 1), y = (n >> kBlockXLog2) & (kLeafDim - 1), z = n >> (kBlockXLog2 + kLeafLog2);
        f(x >> kLeafLog2, ((x & (kLeafDim - 1)) << (2 * kLeafLog2)) | (y << kLeafLog2) | z, slots_[n]);
      }
  }

  void addPiece(int rod, int pieceIndex, const openvdb::CoordBBox& box) {
    const RodPiece& piece = rods_[rod].pieces[pieceIndex];
    if (piece.kind == RodPiece::Kind::Swept) sweep(rod, pieceIndex, piece, box);
    else cap(rod, pieceIndex, piece, box);
  }

private:
  // Slot of voxel (i, j, k) in its block, x fastest: a row's voxels are neighbours in memory and share
  // a word of `filled_`.
  static int offset(int i, int j, int k) {
    return ((k & (kLeafDim - 1)) << (kBlockXLog2 + kLeafLog2)) | ((j & (kLeafDim - 1)) << kBlockXLog2) | (i & (kBlockX - 1));
  }

  // The rows j of layer k that meet the infinite cylinder of radius `reach` around the piece's axis.
  // With w the offset of a voxel centre from the axis point, a row meets the cylinder where the
  // discriminant of |w|^2 - (w.e)^2 = reach^2 in i is >= 0: a quadratic in j whose leading
  // coefficient works out to -(vx vy e_z)^2, so the rows form one interval (all rows when e_z = 0).
  bool clipRowsToAxis(const RodPiece& piece, int k, int& lo, int& hi) const {
    const double vx = grid_.voxelSize.x(), vy = grid_.voxelSize.y();
    const geometry::Vec3& e = piece.axisDirection;
    const geometry::Vec3 w(grid_.origin.x() - piece.axisPoint.x(), grid_.origin.y() - piece.axisPoint.y(),
                           grid_.origin.z() + k * grid_.voxelSize.z() - piece.axisPoint.z());
    const double alpha = vx * vx * (1.0 - e.x() * e.x());
    if (alpha <= 1e-9 * vx * vx) return true;  // axis along x: clipToAxis returns every i; keep every j too
    const double we = w.dot(e);
    const double b0 = vx * (w.x() - we * e.x()), b1 = -vx * vy * e.y() * e.x();
    const double g0 = w.squaredNorm() - we * we - piece.reach * piece.reach;
    const double g1 = 2.0 * vy * (w.y() - we * e.y()), g2 = vy * vy * (1.0 - e.y() * e.y());
    const double A = b1 * b1 - alpha * g2, B = 2.0 * b0 * b1 - alpha * g1, C = b0 * b0 - alpha * g0;
    if (!(A < -1e-12 * vx * vx * vy * vy)) return true;  // axis (nearly) in the layer: no bound in j
    const double disc = B * B - 4.0 * A * C;
    if (disc < 0.0) return false;
    const double root = std::sqrt(disc);
    // A < 0: D(j) >= 0 between the roots.
    lo = std::max(lo, clampToInt(std::ceil((-B + root) / (2.0 * A) - kClipMargin)));
    hi = std::min(hi, clampToInt(std::floor((-B - root) / (2.0 * A) + kClipMargin)));
    return lo <= hi;
  }

  // The row (j, k) restricted to the infinite cylinder of radius `reach` around the piece's axis.
  bool clipToAxis(const RodPiece& piece, int j, int k, int& lo, int& hi) const {
    const double vx = grid_.voxelSize.x();
    const geometry::Vec3 w0(grid_.origin.x() - piece.axisPoint.x(), grid_.origin.y() + j * grid_.voxelSize.y() - piece.axisPoint.y(),
                            grid_.origin.z() + k * grid_.voxelSize.z() - piece.axisPoint.z());
    const geometry::Vec3& e = piece.axisDirection;
    const double we = w0.dot(e);
    // |w0 + i s|^2 - ((w0 + i s) . e)^2 <= reach^2 with s = (vx, 0, 0): alpha i^2 + 2 beta i + gamma <= 0.
    const double alpha = vx * vx * (1.0 - e.x() * e.x());
    const double beta = vx * (w0.x() - we * e.x());
    const double gamma = w0.squaredNorm() - we * we - piece.reach * piece.reach;
    if (alpha <= 1e-9 * vx * vx) return true;  // row (nearly) parallel to the axis: the other clips bound it
    const double disc = beta * beta - alpha * gamma;
    if (disc < 0.0) return false;
    const double root = std::sqrt(disc);
    lo = std::max(lo, clampToInt(std::ceil((-beta - root) / alpha - kClipMargin)));
    hi = std::min(hi, clampToInt(std::floor((-beta + root) / alpha + kClipMargin)));
    return lo <= hi;
  }

  Candidate exact(int rod, int pieceIndex, int i, int j, int k) {
    ++exactEvaluations;
    const openvdb::Vec3d p = grid_.worldPoint(openvdb::Coord(i, j, k));
    const geometry::Rod& r = structure_.rods[rod];
    const geometry::RodHit hit = r.classify(geometry::Vec3(p.x(), p.y(), p.z()));
    if (!hit.inside) return {};
    return {hit.depth, 0.0f, static_cast<float>(r.modulus().value(hit.u)), rod, pieceIndex};
  }

  // The overlap rule. Near ties between approximate depths are settled on exact depths, so the
  // winner is the one the exact test would pick; depths within kTieTolerance are equal (lower rod
  // wins), which spares the exact test where round caps of rods meeting at a node coincide.
  void offer(Candidate c, int i, int j, int k) {
    const int n = offset(i, j, k);
    std::uint64_t& word = filled_[n >> 6];
    const std::uint64_t bit = std::uint64_t(1) << (n & 63);
    Candidate& s = slots_[n];
    if (!(word & bit)) {
      if (c.inside()) {
        s = c;
        word |= bit;
      }
      return;
    }
    if (std::abs(s.depth - c.depth) <= double(s.band) + double(c.band) + kTieTolerance && (s.band > 0.0f || c.band > 0.0f)) {
      if (s.band > 0.0f) s = exact(s.rod, s.piece, i, j, k);
      if (c.band > 0.0f) c = exact(c.rod, c.piece, i, j, k);
      if (!s.inside()) {  // the exact test overturned the approximate claim
        if (c.inside()) s = c;
        else word &= ~bit;
        return;
      }
    }
    if (!c.inside()) return;
    const double gain = c.depth - s.depth;
    if (gain > kTieTolerance || (gain >= -kTieTolerance && (c.rod < s.rod || (c.rod == s.rod && c.piece < s.piece))))
      s = c;
  }

  void sweep(int rod, int pieceIndex, const RodPiece& piece, const openvdb::CoordBBox& box) {
    const RodPieces& rp = rods_[rod];
    const IndexForm& planeA = rp.planes[piece.plane];
    const IndexForm& planeB = rp.planes[piece.plane + 1];
    const double iA = rp.inverseHalfWidth, iB = rp.inverseHalfHeight;
    const bool rectangle = structure_.rods[rod].section().shape == geometry::SectionShape::Rectangle;
    const double band = piece.normalizedRadiusBand;
    const bool bounded = std::isfinite(band) && band < 1.0;
    const float floatBand = bandAsFloat(band);
    const double inner = bounded ? 1.0 - band : -1.0, outer = bounded ? 1.0 + band : std::numeric_limits<double>::infinity();
    const double innerSq = inner > 0.0 ? inner * inner : -1.0, outerSq = outer * outer;
    // Layers, then rows, that can hold a voxel of the slab a >= 0 > b within the box: the extremes of
    // the planes over the box's i (and j) bound them before any row is set up.
    const auto extreme = [](double g, int from, int to, bool largest) {
      return largest ? std::max(g * from, g * to) : std::min(g * from, g * to);
    };
    const openvdb::Coord &bmin = box.min(), &bmax = box.max();
    const double aMaxI = extreme(planeA.gx, bmin.x(), bmax.x(), true), bMinI = extreme(planeB.gx, bmin.x(), bmax.x(), false);
    int kLo = bmin.z(), kHi = bmax.z();
    if (!clipHalfLine(planeA.c + aMaxI + extreme(planeA.gy, bmin.y(), bmax.y(), true), planeA.gz, kLo, kHi) ||
        !clipHalfLine(-(planeB.c + bMinI + extreme(planeB.gy, bmin.y(), bmax.y(), false)), -planeB.gz, kLo, kHi))
      return;
    for (int k = kLo; k <= kHi; ++k) {
      int jLo = bmin.y(), jHi = bmax.y();
      if (!clipHalfLine(planeA.c + planeA.gz * k + aMaxI, planeA.gy, jLo, jHi) ||
          !clipHalfLine(-(planeB.c + planeB.gz * k + bMinI), -planeB.gy, jLo, jHi) || !clipRowsToAxis(piece, k, jLo, jHi))
        continue;
      for (int j = jLo; j <= jHi; ++j) {
        const double aRow = planeA.row(j, k), bRow = planeB.row(j, k);
        int lo = bmin.x(), hi = bmax.x();
        if (!clipHalfLine(aRow, planeA.gx, lo, hi) || !clipHalfLine(-bRow, -planeB.gx, lo, hi) ||
            !clipToAxis(piece, j, k, lo, hi))
          continue;
        const double x1aRow = piece.x1Begin.row(j, k), x2aRow = piece.x2Begin.row(j, k);
        const double x1bRow = piece.x1End.row(j, k), x2bRow = piece.x2End.row(j, k);
        for (int i = lo; i <= hi; ++i) {
          const double a = aRow + planeA.gx * i, b = bRow + planeB.gx * i;
          if (!(a >= 0.0 && b < 0.0)) continue;
          const detail::SweptEstimate e =
              detail::estimateSwept(piece, a, b, x1aRow + piece.x1Begin.gx * i, x2aRow + piece.x2Begin.gx * i,
                                    x1bRow + piece.x1End.gx * i, x2bRow + piece.x2End.gx * i);
          double gauge;
          bool sureInside, sureOutside;
          if (rectangle) {
            gauge = std::max(std::abs(e.x1) * iA, std::abs(e.x2) * iB);
            sureOutside = gauge > outer;
            sureInside = gauge < inner;
          } else {
            const double g2 = (e.x1 * iA) * (e.x1 * iA) + (e.x2 * iB) * (e.x2 * iB);
            sureOutside = g2 > outerSq;
            sureInside = g2 < innerSq;
            gauge = sureInside ? std::sqrt(g2) : 0.0;
          }
          if (sureOutside) continue;
          if (sureInside)
            offer({1.0 - gauge, floatBand, static_cast<float>(detail::estimateModulus(piece, e.lambda)), rod, pieceIndex},
                  i, j, k);
          else
            offer(exact(rod, pieceIndex, i, j, k), i, j, k);
        }
      }
    }
  }

  void cap(int rod, int pieceIndex, const RodPiece& piece, const openvdb::CoordBBox& box) {
    const RodPieces& rp = rods_[rod];
    const geometry::Rod& r = structure_.rods[rod];
    const IndexForm& plane = rp.planes[piece.plane];
    const bool atEnd = piece.kind == RodPiece::Kind::EndCap, round = r.caps() == geometry::CapStyle::Round;
    // Beyond the plane: a >= 0 past the end, a < 0 before the beginning (the complements of the
    // swept pieces' conditions, evaluated identically).
    const double sign = atEnd ? 1.0 : -1.0;
    const double nearPlane = capPlaneBand(r.section().boundingRadius());
    const double invCap = rp.inverseCapRadius;
    constexpr double kCapBand = 1e-9;  // round-off in the cap's distance, relative to its radius
    const float endModulus = static_cast<float>(r.modulus().value(atEnd ? r.modulus().domainEnd() : r.modulus().domainBegin()));
    for (int k = box.min().z(); k <= box.max().z(); ++k) {
      for (int j = box.min().y(); j <= box.max().y(); ++j) {
        const double aRow = plane.row(j, k);
        int lo = box.min().x(), hi = box.max().x();
        if (!clipHalfLine(sign * aRow, sign * plane.gx, lo, hi) || !clipToAxis(piece, j, k, lo, hi)) continue;
        const double wy = piece.capOffset[1].row(j, k), wz = piece.capOffset[2].row(j, k);
        const double wyz = wy * wy + wz * wz;
        for (int i = lo; i <= hi; ++i) {
          const double a = aRow + plane.gx * i;
          if (atEnd ? !(a >= 0.0) : !(a < 0.0)) continue;
          if (std::abs(a) <= nearPlane) {
            offer(exact(rod, pieceIndex, i, j, k), i, j, k);
            continue;
          }
          if (!round) continue;
          const double wx = piece.capOffset[0].row(j, k) + piece.capOffset[0].gx * i;
          const double g = std::sqrt(wx * wx + wyz) * invCap;
          if (g > 1.0 + kCapBand) continue;
          // Inside for sure; the depth's round-off (1e-9 of the radius at most) is within the tie
          // tolerance, so it counts as exact.
          if (g < 1.0 - kCapBand)
            offer({1.0 - g, 0.0f, endModulus, rod, pieceIndex}, i, j, k);
          else
            offer(exact(rod, pieceIndex, i, j, k), i, j, k);
        }
      }
    }
  }

  const geometry::RodStructure& structure_;
  const std::vector<RodPieces>& rods_;
  const PrinterGrid& grid_;
  static constexpr int kWords = kBlockVoxels / 64;
  std::array<Candidate, kBlockVoxels> slots_{};
  std::array<std::uint64_t, kWords> filled_{};
};

}  // namespace

Rasterizer::Rasterizer(const geometry::RodStructure& structure, const PrinterGrid& grid, RasterOptions options)
    : structure_(&structure), grid_(grid), options_(options) {
  rods_.resize(structure.rods.size());
  tbb::task_arena arena(options_.threads > 0 ? options_.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(std::size_t(0), rods_.size(),
                      [&](std::size_t r) { rods_[r] = detail::buildRodPieces(structure.rods[r], grid_); });
  });
}

Rasterizer::~Rasterizer() = default;
Rasterizer::Rasterizer(Rasterizer&&) noexcept = default;
Rasterizer& Rasterizer::operator=(Rasterizer&&) noexcept = default;

std::size_t Rasterizer::pieceCount() const {
  std::size_t n = 0;
  for (const RodPieces& r : rods_) n += r.pieces.size();
  return n;
}

Rasterization Rasterizer::rasterizeLayers(int zBegin, int zEnd) const {
  tbb::task_arena arena(options_.threads > 0 ? options_.threads : tbb::task_arena::automatic);
  return arena.execute([&] { return run(zBegin, zEnd); });
}

Rasterization Rasterizer::run(int zBegin, int zEnd) const {
  Rasterization out;
  out.grid = openvdb::FloatGrid::create(0.0f);
  out.grid->setName(kModulusGridName);
  out.grid->setTransform(grid_.transform());
  out.grid->setGridClass(openvdb::GRID_UNKNOWN);
  out.voxelsPerRod.assign(rods_.size(), 0);
  zBegin = std::max(zBegin, 0);
  zEnd = std::min(zEnd, grid_.dims.z());
  if (zBegin >= zEnd) return out;

  // Which pieces reach which leaves (within the band).
  std::vector<std::vector<Entry>> perRod(rods_.size());
  tbb::parallel_for(std::size_t(0), rods_.size(), [&](std::size_t r) {
    const RodPieces& rod = rods_[r];
    if (rod.box.empty() || rod.box.max().z() < zBegin || rod.box.min().z() >= zEnd) return;
    for (std::size_t p = 0; p < rod.pieces.size(); ++p) {
      openvdb::CoordBBox b = rod.pieces[p].box;
      b.min().z() = std::max(b.min().z(), zBegin);
      b.max().z() = std::min(b.max().z(), zEnd - 1);
      if (b.empty()) continue;
      for (int k = b.min().z() >> kLeafLog2; k <= b.max().z() >> kLeafLog2; ++k)
        for (int j = b.min().y() >> kLeafLog2; j <= b.max().y() >> kLeafLog2; ++j)
          for (int i = b.min().x() >> kBlockXLog2; i <= b.max().x() >> kBlockXLog2; ++i)
            perRod[r].push_back({blockKey(i, j, k), std::uint32_t(r), std::uint32_t(p)});
    }
  });
  std::vector<Entry> entries;
  {
    std::size_t total = 0;
    for (const auto& v : perRod) total += v.size();
    entries.reserve(total);
    for (auto& v : perRod) {
      entries.insert(entries.end(), v.begin(), v.end());
      std::vector<Entry>().swap(v);
    }
  }
  tbb::parallel_sort(entries.begin(), entries.end());
  std::vector<std::size_t> groupStart;
  for (std::size_t e = 0; e < entries.size(); ++e)
    if (e == 0 || entries[e].block != entries[e - 1].block) groupStart.push_back(e);
  groupStart.push_back(entries.size());
  const std::size_t groups = groupStart.size() - 1;

  // Each block built by one task from its pieces, in sorted order.
  struct ThreadState {
    std::unique_ptr<LeafBuilder> builder;
    std::vector<std::uint64_t> voxelsPerRod;
  };
  tbb::enumerable_thread_specific<ThreadState> states;
  std::vector<std::array<std::unique_ptr<LeafT>, kBlockLeaves>> leaves(groups);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, groups), [&](const tbb::blocked_range<std::size_t>& range) {
    ThreadState& state = states.local();
    if (!state.builder) {
      state.builder = std::make_unique<LeafBuilder>(*structure_, rods_, grid_);
      state.voxelsPerRod.assign(rods_.size(), 0);
    }
    LeafBuilder& builder = *state.builder;
    for (std::size_t g = range.begin(); g != range.end(); ++g) {
      const openvdb::Coord origin = blockOrigin(entries[groupStart[g]].block);
      openvdb::CoordBBox blockBox(origin, origin + openvdb::Coord((kLeafDim << kBlockLeavesLog2) - 1, kLeafDim - 1, kLeafDim - 1));
      blockBox.min().z() = std::max(blockBox.min().z(), zBegin);
      blockBox.max().z() = std::min(blockBox.max().z(), zEnd - 1);
      builder.clear();
      bool touched = false;
      for (std::size_t e = groupStart[g]; e < groupStart[g + 1]; ++e) {
        openvdb::CoordBBox b = rods_[entries[e].rod].pieces[entries[e].piece].box;
        b.intersect(blockBox);
        if (b.empty()) continue;
        builder.addPiece(int(entries[e].rod), int(entries[e].piece), b);
        touched = true;
      }
      if (!touched) continue;
      auto& blockLeaves = leaves[g];
      builder.forEachFilled([&](int leafInBlock, int offset, const Candidate& c) {
        std::unique_ptr<LeafT>& leaf = blockLeaves[static_cast<std::size_t>(leafInBlock)];
        if (!leaf) leaf = std::make_unique<LeafT>(origin.offsetBy(leafInBlock * kLeafDim, 0, 0), 0.0f, false);
        leaf->setValueOn(openvdb::Index(offset), c.value);
        ++state.voxelsPerRod[c.rod];
      });
    }
  });

  for (ThreadState& s : states) {
    out.exactEvaluations += s.builder->exactEvaluations;
    for (std::size_t r = 0; r < rods_.size(); ++r) out.voxelsPerRod[r] += s.voxelsPerRod[r];
  }
  openvdb::FloatTree& tree = out.grid->tree();
  for (auto& blockLeaves : leaves)
    for (std::unique_ptr<LeafT>& leaf : blockLeaves)
      if (leaf) tree.addLeaf(leaf.release());
  return out;
}

Rasterization rasterize(const geometry::RodStructure& structure, const PrinterGrid& grid, RasterOptions options) {
  return Rasterizer(structure, grid, options).rasterize();
}

}  // namespace rodfab::voxel
