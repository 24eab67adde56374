// Internal to voxel/: the builder of one block of the rasterizer (64 x 8 x 8 voxels): a slot per voxel
// holding the best candidate so far, the overlap rule of rasterize.hpp between candidates, and the
// three ways a piece fills slots (swept pieces, sweep.cpp; round and flat caps, cap.cpp; pieces with
// no error bound, by the exact test). The slot and overlap functions are inline here because the
// swept and cap loops call them per voxel.
#pragma once

#include "voxel/raster_clips.hpp"
#include "voxel/tree_assembly.hpp"

#include <openvdb/openvdb.h>

#include <array>
#include <bit>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <vector>

namespace rodfab::voxel::detail {

// One rod as a candidate for a voxel, as the exact test and the cold paths of the overlap rule see it.
struct Candidate {
  double depth = -std::numeric_limits<double>::infinity();
  float errorBound = 0.0f;  // bound on |depth - exact depth|, rounded up; 0 when the exact test computed it
  float value = 0.0f;
  int rod = -1;       // -1: outside (the exact test found the centre outside the rod)
  int piece = -1;
  bool inside() const { return rod >= 0; }
};

using LeafT = openvdb::FloatTree::LeafNodeType;
using BlockLeaves = std::array<std::unique_ptr<LeafT>, kBlockLeaves>;

class LeafBuilder {
public:
  LeafBuilder(const geometry::RodStructure& structure, const std::vector<RodPieces>& rods, const PrinterGrid& grid,
              const std::function<bool()>& interrupted)
      : voxelsPerRod(structure.rods.size(), 0), structure_(structure), rods_(rods), grid_(grid), interrupted_(interrupted),
        deferredDepth_(structure.rods.size()) {
    for (std::size_t r = 0; r < deferredDepth_.size(); ++r)
      deferredDepth_[r] = structure.rods[r].section().shape != geometry::SectionShape::Rectangle;
  }

  std::uint64_t exactEvaluations = 0;
  std::uint64_t quadsSettledAtOnce = 0;  // addFourSurelyInside's four-lane outcomes (Rasterization::quadsSettledAtOnce)
  std::vector<std::uint64_t> voxelsPerRod;  // filled slots won, per rod, over every block built

  // Slots hold a candidate of a rod the voxel lies in exactly where their bit in `filled_` is set:
  // clearing a block costs 512 bytes, not the 96 KiB of slots.
  void clear() {
    filled_.fill(0);
    memoRod_ = -1;
  }
  // Writes the block's filled slots into leaves: leaves[l], the block's l-th leaf along x, is created
  // (values 0) where any of its voxels is filled. Slots are row by row (see offset) and leaves column by column, so a leaf's value mask
  // is the transpose of `filled_`: word x of leaf l holds bit r = (y, z) for column i = 8 l + x, where
  // filled_ holds bit i of row r. Per leaf, the values go in by 4 x 4 transposes of the slots (the
  // slot's value where the bit is set, else the leaf's 0: the slots of an empty voxel hold some
  // earlier block's value, never an indeterminate one, see value_), and the mask words come from the
  // 64 row bytes by movemask, eight bits a row at a time.
  // The leaves come from `spares` (tree_assembly.hpp) while there are any, each taking the spare index
  // `nextSpare` counts out (shared by the threads, so the reused leaves are the first ones; a block takes
  // the indices of all its leaves at once).
  void emit(const openvdb::Coord& origin, SpareNodes<openvdb::FloatTree>& spares, std::atomic<std::size_t>& nextSpare,
            BlockLeaves& leaves) const;

  // Fills the slots the piece reaches within `box`; throws Interrupted once the exact test saw the interrupt.
  void addPiece(int rod, int pieceIndex, const openvdb::CoordBBox& box);

private:
  // Slot of voxel (i, j, k) in its block: row by row, the 64 voxels of a row (j, k) along x
  // contiguous, so the swept loop fills four neighbours with one vector store, and a voxel's bit of
  // `filled_` is bit i & (kBlockX - 1) of the row's word. Rows are numbered (y, z) as a leaf numbers
  // the voxels of one x, which makes emit a transpose.
  static int offset(int i, int j, int k) {
    return (rowOf(j, k) << kBlockXLog2) | (i & (kBlockX - 1));
  }
  static int rowOf(int j, int k) { return ((j & (kLeafDim - 1)) << kLeafLog2) | (k & (kLeafDim - 1)); }
  static std::uint64_t owner(int rod, int piece) { return (std::uint64_t(std::uint32_t(rod)) << 32) | std::uint32_t(piece); }
  // The exact test (Rod::classify) of voxel (i, j, k) against the rod; polls the interrupter (see the definition).
  Candidate exact(int rod, int pieceIndex, int i, int j, int k);

  // A slot stores its depth encoded: the depth itself, except for approximate candidates of rods with
  // round sections (errorBound > 0 and deferredDepth_), where it stores the gauge squared, (1 - depth)^2:
  // the square root is only taken when another rod competes for the voxel, and it is the same
  // expression the depth always came from. Approximate candidates always have errorBound > 0
  // (normalizedRadiusErrorBound has a 1e-12 floor) and exact ones 0.
  double decodedDepth(double encodedDepth, float errorBound, int rod) const {
    return errorBound > 0.0f && deferredDepth_[static_cast<std::size_t>(rod)] ? 1.0 - std::sqrt(encodedDepth) : encodedDepth;
  }
  // Four neighbouring slots n .. n + 3 of one row (see offset), as four stores would fill them.
  [[gnu::always_inline]] void storeFour(int n, Double4 encodedDepth, Float4 value, Float4 bounds, Owner4 owners) {
    std::memcpy(&encodedDepth_[static_cast<std::size_t>(n)], &encodedDepth, sizeof encodedDepth);
    std::memcpy(&value_[static_cast<std::size_t>(n)], &value, sizeof value);
    std::memcpy(&errorBound_[static_cast<std::size_t>(n)], &bounds, sizeof bounds);
    std::memcpy(&owner_[static_cast<std::size_t>(n)], &owners, sizeof owners);
  }
  // Slots n .. n + 3 of one row, when they lie in the row and are all empty, filled with one store and
  // the bits of `lanes` set (lanes not in `lanes`, past the row's end, go to empty slots whose bits stay
  // clear: no candidate is ever read from an empty slot, and emit masks their values out). False, and
  // nothing done, otherwise.
  [[gnu::always_inline]] bool storeFourIntoEmpty(int n, Double4 encodedDepth, Float4 value, Float4 bounds, Owner4 owners, unsigned lanes) {
    std::uint64_t& word = filled_[static_cast<std::size_t>(n >> kBlockXLog2)];
    const int shift = n & (kBlockX - 1);
    if (shift > kBlockX - 4 || ((word >> shift) & 0xfu) != 0) return false;
    storeFour(n, encodedDepth, value, bounds, owners);
    word |= std::uint64_t(lanes) << shift;
    return true;
  }
  void store(int n, double encodedDepth, float errorBound, float value, std::uint64_t who) {
    encodedDepth_[n] = encodedDepth;
    errorBound_[n] = errorBound;
    value_[n] = value;
    owner_[n] = who;
  }

  // An approximate candidate that is inside for sure (depth encoded as in decodedDepth). The common
  // case, an empty slot, is a plain store, and returns 1 for the caller to add to the rod's tally; a
  // filled one goes through the overlap rule.
  [[gnu::always_inline]] int addSurelyInside(int n, double encodedDepth, float errorBound, float value, int rod, int piece, int i, int j, int k) {
    std::uint64_t& word = filled_[n >> 6];
    const std::uint64_t bit = std::uint64_t(1) << (n & 63);
    if (!(word & bit)) {
      store(n, encodedDepth, errorBound, value, owner(rod, piece));
      word |= bit;
      return 1;
    }
    const bool round = deferredDepth_[static_cast<std::size_t>(rod)];
    if (clearOverlap(n, round ? encodedDepth : (1.0 - encodedDepth) * (1.0 - encodedDepth), encodedDepth, errorBound, value, rod, piece))
      return 0;
    const Candidate c{decodedDepth(encodedDepth, errorBound, rod), errorBound, value, rod, piece};
    if (!overlapWithoutExactTest(n, c, encodedDepth)) resolveOverlap(n, c, encodedDepth, i, j, k);
    return 0;
  }
  // Four neighbouring candidates of one row (slots n .. n + 3), inside for sure, some of whose slots
  // are filled (at rods' crossings and nodes): as addSurelyInside would take them one by one. When
  // every filled slot's outcome is clear (clearOverlap's expressions lane by lane, so the same bits and
  // the same stores) the four are settled at once: empty slots and clearly shallower holders take the
  // candidate, the rest stay. Otherwise voxel by voxel. Returns the slots newly filled.
  [[gnu::always_inline]] int addFourSurelyInside(int n, Double4 encodedDepth, Float4 value, float errorBound, int rod, int piece,
                                                 int i, int j, int k) {
    std::uint64_t& word = filled_[static_cast<std::size_t>(n >> 6)];
    const unsigned filled = static_cast<unsigned>(word >> (n & 63)) & 0xfu;
    // Only filled slots are read (the others hold no candidate yet).
    Double4 slotEncoded{}, slotBound{};
    Mask4 isFilled{}, roundSlot{};
    std::array<int, 4> slotRod{};
    for (int l = 0; l < 4; ++l) {
      if (!((filled >> l) & 1u)) continue;
      const auto s = static_cast<std::size_t>(n + l);
      slotRod[static_cast<std::size_t>(l)] = static_cast<int>(owner_[s] >> 32);
      slotEncoded[l] = encodedDepth_[s];
      slotBound[l] = errorBound_[s];
      isFilled[l] = -1;
      roundSlot[l] = deferredDepth_[static_cast<std::size_t>(slotRod[static_cast<std::size_t>(l)])] ? -1 : 0;
    }
    const Mask4 approximate = slotBound > 0.0;
    const Mask4 atHand = (approximate & roundSlot) | (~approximate & (slotEncoded >= 0.0) & (slotEncoded <= 1.0));
    const Double4 slotGaugeSquared = approximate ? slotEncoded : (1.0 - slotEncoded) * (1.0 - slotEncoded);
    const Double4 gaugeSquared =
        deferredDepth_[static_cast<std::size_t>(rod)] ? encodedDepth : (1.0 - encodedDepth) * (1.0 - encodedDepth);
    const Double4 clear = 2.0 * (slotBound + double(errorBound) + kTieTolerance) + 1e-12;
    const Mask4 stays = gaugeSquared - slotGaugeSquared > clear, takes = slotGaugeSquared - gaugeSquared > clear;
    const Mask4 settled = ~isFilled | (atHand & (stays | takes));
    int fresh = 0;
    if (!(settled[0] & settled[1] & settled[2] & settled[3])) {
      for (int l = 0; l < 4; ++l)
        fresh += addSurelyInside(n + l, encodedDepth[l], errorBound, value[l], rod, piece, i + l, j, k);
      return fresh;
    }
    ++quadsSettledAtOnce;
    const std::uint64_t who = owner(rod, piece);
    for (int l = 0; l < 4; ++l) {
      if (!isFilled[l]) {
        store(n + l, encodedDepth[l], errorBound, value[l], who);
        ++fresh;
      } else if (!stays[l]) {
        replaceSlot(n + l, encodedDepth[l], errorBound, value[l], rod, piece, slotRod[static_cast<std::size_t>(l)]);
      }
    }
    word |= std::uint64_t(~filled & 0xfu) << (n & 63);
    return fresh;
  }
  // The overlap rule's outcome without square roots, where it is clear. Both sides are ranked by their
  // gauge squared, g^2 = (1 - depth)^2 with g in [0, 1]: an approximate round-section slot stores it
  // (encoded depth), an exact or cap slot with a depth in [0, 1] gives it as (1 - depth)^2, and the
  // caller passes the candidate's (`gaugeSquared`, in [0, 1]). With both gauges in [0, 1],
  // |sqrt(a) - sqrt(b)| >= |a - b| / 2, so a difference of squares above 2 (bounds + tie tolerance),
  // plus 1e-12 for the round-off of the depths and squares (below 1e-15), means resolveOverlap finds no
  // near tie and lets the deeper one (the smaller g^2) win: the same outcome, with the same stores.
  // Returns false where resolveOverlap must decide (or the slot's gauge is not at hand: an approximate
  // rectangle, an exact depth outside [0, 1]).
  bool clearOverlap(int n, double gaugeSquared, double encodedDepth, float errorBound, float value, int rod, int piece) {
    const std::uint64_t slotOwner = owner_[static_cast<std::size_t>(n)];
    const int slotRod = static_cast<int>(slotOwner >> 32);
    const float slotBound = errorBound_[static_cast<std::size_t>(n)];
    const double slotEncoded = encodedDepth_[static_cast<std::size_t>(n)];
    double slotGaugeSquared;
    if (slotBound > 0.0f) {
      if (!deferredDepth_[static_cast<std::size_t>(slotRod)]) return false;
      slotGaugeSquared = slotEncoded;
    } else {
      if (!(slotEncoded >= 0.0 && slotEncoded <= 1.0)) return false;
      slotGaugeSquared = (1.0 - slotEncoded) * (1.0 - slotEncoded);
    }
    const double clear = 2.0 * (double(slotBound) + double(errorBound) + kTieTolerance) + 1e-12;
    if (gaugeSquared - slotGaugeSquared > clear) return true;  // the candidate is clearly shallower: the slot stays
    if (slotGaugeSquared - gaugeSquared > clear) {              // clearly deeper: it takes the slot
      replaceSlot(n, encodedDepth, errorBound, value, rod, piece, slotRod);
      return true;
    }
    return false;
  }
  // A round cap's candidate inside it for sure, gauge g < 1 (depth 1 - g, exact up to round-off within
  // the tie tolerance). At a node nearly all of a cap lies inside the rods around it, whose deeper
  // candidates already hold most of its slots: clearOverlap settles those without a square root.
  void addCapCandidate(int n, double g, float value, int rod, int piece, int i, int j, int k) {
    std::uint64_t& word = filled_[static_cast<std::size_t>(n >> 6)];
    const std::uint64_t bit = std::uint64_t(1) << (n & 63);
    const double depth = 1.0 - g;
    if (!(word & bit)) {
      store(n, depth, 0.0f, value, owner(rod, piece));
      word |= bit;
      ++voxelsPerRod[static_cast<std::size_t>(rod)];
      return;
    }
    if (clearOverlap(n, g * g, depth, 0.0f, value, rod, piece)) return;
    const Candidate c{depth, 0.0f, value, rod, piece};
    if (!overlapWithoutExactTest(n, c, depth)) resolveOverlap(n, c, depth, i, j, k);
  }
  // Round-cap candidates inside for sure (gauges g < 1) for the lanes set in `lanes` of slots n .. n + 3
  // of one row, where those four slots lie in the row and are all empty: one store (storeFourIntoEmpty),
  // as addCapCandidate would fill them one by one. False, and nothing done, otherwise.
  [[gnu::always_inline]] bool capsIntoEmptySlots(int n, Double4 g, unsigned lanes, float value, int rod, int piece) {
    if (!storeFourIntoEmpty(n, 1.0 - g, Float4{} + value, Float4{}, Owner4{} + owner(rod, piece), lanes)) return false;
    voxelsPerRod[static_cast<std::size_t>(rod)] += static_cast<std::uint64_t>(std::popcount(lanes));
    return true;
  }
  // Four neighbouring round-cap candidates of one row (slots n .. n + 3), inside for sure (gauges g < 1),
  // as addCapCandidate would take them one by one. Their common fate at a node, four filled slots each
  // clearly deeper than the cap, is settled with one comparison of four lanes: clearOverlap's
  // expressions lane by lane (the candidate's error bound is 0, so `clear` gets the same bits). Any
  // other case goes voxel by voxel.
  [[gnu::always_inline]] void addFourCapCandidates(int n, Double4 g, float value, int rod, int piece, int i, int j, int k) {
    if (capsIntoEmptySlots(n, g, 0xfu, value, rod, piece)) return;
    if (((filled_[static_cast<std::size_t>(n >> 6)] >> (n & 63)) & 0xfu) == 0xfu) {
      Double4 slotEncoded;
      Float4 slotBoundFloat;
      std::memcpy(&slotEncoded, &encodedDepth_[static_cast<std::size_t>(n)], sizeof slotEncoded);
      std::memcpy(&slotBoundFloat, &errorBound_[static_cast<std::size_t>(n)], sizeof slotBoundFloat);
      const Double4 slotBound = __builtin_convertvector(slotBoundFloat, Double4);
      Mask4 roundSlot;
      for (int l = 0; l < 4; ++l)
        roundSlot[l] = deferredDepth_[static_cast<std::size_t>(owner_[static_cast<std::size_t>(n + l)] >> 32)] ? -1 : 0;
      const Mask4 approximate = slotBound > 0.0;
      // Where the slot's gauge is at hand (see clearOverlap); elsewhere the lane is not clear.
      const Mask4 atHand = (approximate & roundSlot) | (~approximate & (slotEncoded >= 0.0) & (slotEncoded <= 1.0));
      const Double4 slotGaugeSquared = approximate ? slotEncoded : (1.0 - slotEncoded) * (1.0 - slotEncoded);
      const Double4 clear = 2.0 * (slotBound + 0.0 + kTieTolerance) + 1e-12;
      const Mask4 slotStays = atHand & (g * g - slotGaugeSquared > clear);
      if (slotStays[0] & slotStays[1] & slotStays[2] & slotStays[3]) return;
    }
    for (int l = 0; l < 4; ++l) addCapCandidate(n + l, g[l], value, rod, piece, i + l, j, k);
  }
  // A candidate with its depth at hand (exact, or caps), possibly outside.
  void addCandidate(const Candidate& c, int n, int i, int j, int k) {
    std::uint64_t& word = filled_[n >> 6];
    const std::uint64_t bit = std::uint64_t(1) << (n & 63);
    if (!(word & bit)) {
      if (c.inside()) {
        store(n, c.depth, c.errorBound, c.value, owner(c.rod, c.piece));
        word |= bit;
        ++voxelsPerRod[static_cast<std::size_t>(c.rod)];
      }
      return;
    }
    if (!overlapWithoutExactTest(n, c, c.depth)) resolveOverlap(n, c, c.depth, i, j, k);
  }

  // The overlap rule, in one place: a candidate `gain` deeper than the slot's holder (sRod, sPiece)
  // takes the slot when it is deeper by more than kTieTolerance, or within it and of a lower rod (then
  // a lower piece). It decides which rod owns a voxel, so the job's bytes.
  [[gnu::always_inline]] static bool takesSlot(double gain, const Candidate& c, int sRod, int sPiece) {
    return gain > kTieTolerance || (gain >= -kTieTolerance && (c.rod < sRod || (c.rod == sRod && c.piece < sPiece)));
  }
  [[gnu::always_inline]] void replaceSlot(int n, double encodedDepth, float errorBound, float value, int rod, int piece, int oldRod) {
    store(n, encodedDepth, errorBound, value, owner(rod, piece));
    --voxelsPerRod[static_cast<std::size_t>(oldRod)];
    ++voxelsPerRod[static_cast<std::size_t>(rod)];
  }

  // resolveOverlap where it needs no exact test (no near tie involving an approximate depth): the same
  // expressions in the same order, so the same decision, inline and without a copy of the slot. At
  // the lattice's nodes this is nearly every overlap of a round cap with the rods around it.
  // Returns false where resolveOverlap must decide (a near tie).
  [[gnu::always_inline]] bool overlapWithoutExactTest(int n, const Candidate& c, double cEncodedDepth) {
    const std::uint64_t slotOwner = owner_[static_cast<std::size_t>(n)];
    const int sRod = static_cast<int>(slotOwner >> 32);
    const float sBound = errorBound_[static_cast<std::size_t>(n)];
    const double sDepth = decodedDepth(encodedDepth_[static_cast<std::size_t>(n)], sBound, sRod);
    if (std::abs(sDepth - c.depth) <= double(sBound) + double(c.errorBound) + kTieTolerance && (sBound > 0.0f || c.errorBound > 0.0f))
      return false;
    const double gain = c.depth - sDepth;
    const int sPiece = static_cast<int>(slotOwner & 0xffffffffu);
    if (c.inside() && takesSlot(gain, c, sRod, sPiece)) replaceSlot(n, cEncodedDepth, c.errorBound, c.value, c.rod, c.piece, sRod);
    return true;
  }

  // The overlap rule between filled slot n and candidate c (cEncodedDepth: c's depth as the slot would
  // store it). Near ties between approximate depths are settled on exact depths, so the winner is the
  // one the exact test would pick; depths within kTieTolerance are equal (lower rod wins), which spares
  // the exact test where round caps of rods meeting at a node coincide.
  [[gnu::noinline]] void resolveOverlap(int n, Candidate c, double cEncodedDepth, int i, int j, int k);

  // The swept piece's voxels (sweep.cpp), in named steps (inlined into sweep's clones): the layers
  // and rows of the slab, four rows set up at once (sweepLayer), each row four voxels a step
  // (sweepRow: sweptQuad evaluates, settleQuad stores or decides voxel by voxel).
  void sweep(int rod, int pieceIndex, const RodPiece& piece, const openvdb::CoordBBox& box);
  struct SweptPiece;  // what the steps share about the piece (sweep.cpp)
  struct SweptQuad;
  struct SweptRowStart;
  // Full: the piece's estimate has terms beyond the blends and their quadratic terms (needsFullEstimate).
  template <bool Full>
  int sweepLayer(const SweptPiece& s, const openvdb::CoordBBox& box, const AxisCylinder& cylinder, int k, int jLo, int jHi);
  template <bool Full>
  int sweepRow(const SweptPiece& s, const SweptRowStart& r, int lo, int hi, int j, int k);
  template <bool Full>
  SweptQuad sweptQuad(bool rectangle, const SweptRowStart& r, Double4 iv) const;
  int settleQuad(const SweptPiece& s, const SweptQuad& q, int row, int i, int hi, int j, int k);
  // Every voxel of the piece's box within its reach of the chord, decided by the exact test; once per
  // voxel and rod in a block (exact pieces of a tight bend overlap, and the test already decides the
  // whole rod).
  void exactRegion(int rod, int pieceIndex, const RodPiece& piece, const openvdb::CoordBBox& box);
  // A round or flat cap's voxels (cap.cpp).
  void cap(int rod, int pieceIndex, const RodPiece& piece, const openvdb::CoordBBox& box);
  struct CapPiece;  // what a cap's rows share (cap.cpp)
  void capRowVoxels(const CapPiece& c, double aRow, double wxRow, double wyz, int lo, int hi, int j, int k);

  const geometry::RodStructure& structure_;
  const std::vector<RodPieces>& rods_;
  const PrinterGrid& grid_;
  const std::function<bool()>& interrupted_;
  bool interruptSeen_ = false;  // exact() saw the interrupt: the block is abandoned (see exact)
  std::vector<unsigned char> deferredDepth_;  // per rod: round section (see decodedDepth)
  static constexpr int kRows = kLeafDim * kLeafDim;
  static constexpr int kWords = kBlockVoxels / 64;
  static_assert(kWords == kRows && kBlockX == 64, "a word of filled_ per row (y, z) of the block: bit x");
  // The slots, field by field (24 bytes a voxel), read only where `filled_` says they were written
  // (but for emit's reads of value_): left uninitialized, so that setting up a builder does not touch
  // their 80 KiB.
  std::array<double, kBlockVoxels> encodedDepth_;
  std::array<float, kBlockVoxels> errorBound_;
  std::array<float, kBlockVoxels> value_{};  // zeroed once: emit reads the slots of a row's empty voxels too
  std::array<std::uint64_t, kBlockVoxels> owner_;
  std::array<std::uint64_t, kWords> filled_{};
  std::array<std::uint64_t, kWords> memo_{};  // voxels of the block exactly tested for rod memoRod_
  int memoRod_ = -1;
  // The coefficients of the piece sweep() is on, in four lanes (set once per piece). A member rather
  // than sweep's local: GCC kept a local's 16 lanes in registers it then spilled, copied between stack
  // slots or broadcast again at every row (some 40 instructions a row, with 1.3 quads a row on the
  // curved lattice); the builder's memory, which the out-of-line calls in the loop (the exact test,
  // resolveOverlap) may change, stays where it is, read by the vector instructions as operands.
  SweptLanes swept_;
};

}  // namespace rodfab::voxel::detail
