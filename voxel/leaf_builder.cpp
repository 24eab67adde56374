#include "voxel/leaf_builder.hpp"

#include <emmintrin.h>
#include <xmmintrin.h>

#include <algorithm>
#include <bit>
#include <cmath>

namespace rodfab::voxel::detail {

namespace {

// Leaf values from the slots of one leaf of a block (see LeafBuilder::emit): values[(x << 6) | r] =
// slots[(r << kBlockXLog2) | x] where bit x of bytes[r] is set, else 0, for x < 8 and the 64 rows r.
// Four rows by four columns at a time: the slots' rows loaded, the empty ones' lanes cleared (and with
// a lane mask, so a kept value keeps its bits), then transposed (SSE2) into four runs of four values of
// the leaf's columns. Groups whose bits are all clear get four runs of 0 where `clearEmpty` (a reused
// leaf holding its old values: each value is written once, where filling the whole leaf with 0 first
// wrote the kept ones twice), else nothing (a new leaf holds 0 already).
void transposeIntoLeaf(const std::array<std::uint8_t, 64>& bytes, const float* slots, float* values, bool clearEmpty) {
  for (int r0 = 0; r0 < 64; r0 += 4) {
    unsigned any = 0;
    __m128i byteOf[4];
    for (int m = 0; m < 4; ++m) {
      any |= bytes[static_cast<std::size_t>(r0 + m)];
      byteOf[m] = _mm_set1_epi32(bytes[static_cast<std::size_t>(r0 + m)]);
    }
    for (int h = 0; h < 2; ++h) {
      if (((any >> (4 * h)) & 0xfu) == 0) {
        if (clearEmpty)
          for (int x = 0; x < 4; ++x) _mm_storeu_ps(values + ((4 * h + x) << (2 * kLeafLog2)) + r0, _mm_setzero_ps());
        continue;
      }
      const __m128i bit = _mm_setr_epi32(1 << (4 * h), 2 << (4 * h), 4 << (4 * h), 8 << (4 * h));
      __m128 row[4];
      for (int m = 0; m < 4; ++m) {
        const __m128 kept = _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_and_si128(byteOf[m], bit), bit));
        row[m] = _mm_and_ps(_mm_loadu_ps(slots + ((r0 + m) << kBlockXLog2) + 4 * h), kept);
      }
      _MM_TRANSPOSE4_PS(row[0], row[1], row[2], row[3]);
      for (int x = 0; x < 4; ++x) _mm_storeu_ps(values + ((4 * h + x) << (2 * kLeafLog2)) + r0, row[x]);
    }
  }
}

}  // namespace

void LeafBuilder::emit(const openvdb::Coord& origin, SpareNodes<openvdb::FloatTree>& spares, std::atomic<std::size_t>& nextSpare,
                       BlockLeaves& leaves) const {
  static_assert(kRows == 64 && kLeafDim == 8, "transposeIntoLeaf's layout");
  std::uint64_t anyRow = 0;
  for (std::uint64_t w : filled_) anyRow |= w;
  // The block's spare indices taken at once: one atomic operation a block, not a leaf (on two threads
  // the counter's cache line went back and forth for every leaf).
  std::size_t count = 0;
  for (int l = 0; l < kBlockLeaves; ++l) count += ((anyRow >> (l * kLeafDim)) & 0xffu) != 0;
  std::size_t spare = count > 0 ? nextSpare.fetch_add(count, std::memory_order_relaxed) : 0;
  for (int l = 0; l < kBlockLeaves; ++l) {
    if (((anyRow >> (l * kLeafDim)) & 0xffu) == 0) continue;
    const bool reused = spares.hasLeaf(spare);  // a new leaf holds 0 already; a reused one its old values (cleared below)
    leaves[static_cast<std::size_t>(l)] = spares.leaf(spare++, origin.offsetBy(l * kLeafDim, 0, 0));
    LeafT& node = *leaves[static_cast<std::size_t>(l)];
    alignas(16) std::array<std::uint8_t, kRows> bytes;
    for (int r = 0; r < kRows; ++r)
      bytes[static_cast<std::size_t>(r)] = static_cast<std::uint8_t>(filled_[static_cast<std::size_t>(r)] >> (l * kLeafDim));
    transposeIntoLeaf(bytes, &value_[static_cast<std::size_t>(l * kLeafDim)], node.buffer().data(), reused);
    for (int x = 0; x < kLeafDim; ++x) {
      // Bit x of every row byte to its top bit (a 64-bit shift moves no bit across a byte's top).
      const __m128i shift = _mm_cvtsi32_si128(kLeafDim - 1 - x);
      std::uint64_t column = 0;
      for (int q = 0; q < kRows / 16; ++q) {
        const __m128i v = _mm_load_si128(reinterpret_cast<const __m128i*>(&bytes[static_cast<std::size_t>(16 * q)]));
        column |= std::uint64_t(static_cast<std::uint16_t>(_mm_movemask_epi8(_mm_sll_epi64(v, shift)))) << (16 * q);
      }
      node.getValueMask().template getWord<std::uint64_t>(openvdb::Index(x)) = column;
    }
  }
}

void LeafBuilder::addPiece(int rod, int pieceIndex, const openvdb::CoordBBox& box) {
  const RodPiece& piece = rods_[rod].pieces[pieceIndex];
  if (piece.kind == RodPiece::Kind::Swept) sweep(rod, pieceIndex, piece, box);
  else if (piece.kind == RodPiece::Kind::Exact) exactRegion(rod, pieceIndex, piece, box);
  else cap(rod, pieceIndex, piece, box);
  if (interruptSeen_) throw Interrupted("rasterizer: interrupted");
}

Candidate LeafBuilder::exact(int rod, int pieceIndex, int i, int j, int k) {
  // The exact test is the one costly step per voxel (a Newton solve per nearby polyline segment):
  // the interrupter is polled between every 64 of them.
  // No throw here: sweep() is a target_clones function, and GCC 12 treats a call to one as unable to
  // throw, so an exception leaving it ended the process (std::terminate). The first poll that sees
  // the interrupt marks the builder; the rest of the piece is skipped and addPiece() throws.
  if (interrupted_ && ++exactEvaluations % 64 == 0 && interrupted_()) interruptSeen_ = true;
  if (!interrupted_) ++exactEvaluations;
  if (interruptSeen_) return {};
  const openvdb::Vec3d p = grid_.worldPoint(openvdb::Coord(i, j, k));
  const geometry::Rod& r = structure_.rods[rod];
  const geometry::RodHit hit = r.classify(geometry::Vec3(p.x(), p.y(), p.z()));
  if (!hit.inside) return {};
  return {hit.depth, 0.0f, static_cast<float>(r.modulus().value(hit.u)), rod, pieceIndex};
}

namespace {

// Both surely inside, with values that agree within the tolerance the pieces' own estimates of E keep
// (1e-6 relative, rod_pieces.cpp): whichever of the two the exact test would pick, the voxel is active
// and its value the same to within what an estimate may be off.
bool sameVoxelEitherWay(const Candidate& s, const Candidate& c) {
  const double a = s.value, b = c.value;
  return s.depth > double(s.errorBound) && c.depth > double(c.errorBound) &&
         std::abs(a - b) <= 1e-6 * std::max({std::abs(a), std::abs(b), 1e-3});
}

}  // namespace

// The overlap rule between filled slot n and candidate c (cEncodedDepth: c's depth as the slot would
// store it). Near ties between approximate depths are settled on exact depths, so the winner is the
// one the exact test would pick, unless either winner makes the same voxel (sameVoxelEitherWay): then
// as a tie. Depths within kTieTolerance are equal (lower rod wins), which spares the exact test where
// round caps of rods meeting at a node coincide; the same values spare it where a rod is listed twice
// a hair apart (every voxel they share ties; a copy of a helix at 0.02 mm cost 4-7 s of exact tests).
void LeafBuilder::resolveOverlap(int n, Candidate c, double cEncodedDepth, int i, int j, int k) {
  const int sRod = static_cast<int>(owner_[n] >> 32);
  Candidate s{decodedDepth(encodedDepth_[n], errorBound_[n], sRod), errorBound_[n], value_[n], sRod,
              static_cast<int>(owner_[n] & 0xffffffffu)};
  double sEncodedDepth = encodedDepth_[n];
  bool sChanged = false;
  const bool nearTie = std::abs(s.depth - c.depth) <= double(s.errorBound) + double(c.errorBound) + kTieTolerance;
  if (nearTie && (s.errorBound > 0.0f || c.errorBound > 0.0f) && sameVoxelEitherWay(s, c)) {
    if (takesSlot(0.0, c, s.rod, s.piece)) replaceSlot(n, cEncodedDepth, c.errorBound, c.value, c.rod, c.piece, s.rod);
    return;
  }
  if (nearTie && (s.errorBound > 0.0f || c.errorBound > 0.0f)) {
    if (s.errorBound > 0.0f) {
      s = exact(s.rod, s.piece, i, j, k);
      sEncodedDepth = s.depth;
      sChanged = true;
    }
    if (c.errorBound > 0.0f) {
      c = exact(c.rod, c.piece, i, j, k);
      cEncodedDepth = c.depth;
    }
    if (!s.inside()) {  // the exact test overturned the approximate candidate
      --voxelsPerRod[static_cast<std::size_t>(sRod)];
      if (c.inside()) {
        store(n, cEncodedDepth, c.errorBound, c.value, owner(c.rod, c.piece));
        ++voxelsPerRod[static_cast<std::size_t>(c.rod)];
      } else {
        filled_[n >> 6] &= ~(std::uint64_t(1) << (n & 63));
      }
      return;
    }
  }
  const double gain = c.depth - s.depth;
  if (c.inside() && takesSlot(gain, c, s.rod, s.piece))
    replaceSlot(n, cEncodedDepth, c.errorBound, c.value, c.rod, c.piece, s.rod);
  else if (sChanged)
    store(n, sEncodedDepth, s.errorBound, s.value, owner(s.rod, s.piece));
}

void LeafBuilder::exactRegion(int rod, int pieceIndex, const RodPiece& piece, const openvdb::CoordBBox& box) {
  if (memoRod_ != rod) {
    memo_.fill(0);
    memoRod_ = rod;
  }
  AxisCylinder cylinder(grid_, piece);
  // The box's voxels of a row as bits of its memo word: a row whose every one is tested already needs
  // no clip (a coil tighter than its section brings thousands of exact pieces to the same rows; their
  // clips were most of what exactRegion cost there).
  const std::uint64_t boxSpan = (~std::uint64_t(0) >> (kBlockX - 1 - (box.max().x() & (kBlockX - 1)))) &
                                (~std::uint64_t(0) << (box.min().x() & (kBlockX - 1)));
  for (int k = box.min().z(); k <= box.max().z(); ++k) {
    int jLo = box.min().y(), jHi = box.max().y();
    if (!cylinder.layer(k, jLo, jLo, jHi)) continue;
    for (int j = jLo; j <= jHi; ++j) {
      if ((memo_[static_cast<std::size_t>(rowOf(j, k))] & boxSpan) == boxSpan) continue;
      RowBounds bounds;
      int lo = box.min().x(), hi = box.max().x();
      if (!cylinder.row(j, bounds) || !bounds.round(lo, hi)) continue;
      // The row's voxels [lo, hi] as bits of its memo word (the box lies in the block), so a voxel
      // already tested costs nothing: where a rod overlaps itself (a coil tighter than its section)
      // thousands of exact pieces reach the same rows, and a test per voxel and piece was most of the
      // work once the exact test got cheap there. The untested ones in increasing i, as before.
      const int row = rowOf(j, k), first = lo & (kBlockX - 1), last = hi & (kBlockX - 1);
      const std::uint64_t span = (~std::uint64_t(0) >> (kBlockX - 1 - last)) & (~std::uint64_t(0) << first);
      std::uint64_t& word = memo_[static_cast<std::size_t>(row)];
      std::uint64_t fresh = span & ~word;
      word |= span;
      for (; fresh != 0; fresh &= fresh - 1) {
        const int x = std::countr_zero(fresh), i = lo - first + x;
        addCandidate(exact(rod, pieceIndex, i, j, k), (row << kBlockXLog2) | x, i, j, k);
      }
    }
  }
}

}  // namespace rodfab::voxel::detail
