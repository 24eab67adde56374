// Rasterization of a rod structure into a sparse grid of Young's modulus at printer resolution.
//
// Membership: a voxel is active when its centre lies inside some rod: the exact test of
// geometry::Rod::classify, whose solid geometry/rod.hpp defines (the union of the rod's smooth pieces,
// cut at kinks and other C0 points; each the section swept along its centerline in frame coordinates,
// plus the rod's caps at every piece end; for rods thinner than their bends this is the closest-point
// rule). Its value is that rod's E(u) at the deepest section through the centre, in MPa.
//
// Overlaps (joints): the voxel takes the value of the rod in which its centre lies deepest, depth
// being 1 - the normalized radius of the section (geometry::RodHit::depth), so the rod whose
// boundary is farthest away wins; equal depths (closer than kDepthTieTolerance, as where the round
// caps of rods meeting at a node coincide) go to the lower rod index. The rule depends on
// nothing but the voxel, so the grid is identical for any thread count and any band of layers.
// Voxels are emitted only inside the design's bounding box (RodStructure::bounds, which holds every
// rod's solid): the part bounds of a job.
//
// How (fast and still exact): each smooth piece of a rod is cut by normal planes of its centerline into
// short pieces with a cheap approximation of a point's frame coordinates and a measured error bound
// (see rod_pieces.hpp). Work is binned by blocks of eight OpenVDB leaves along x (64 x 8 x 8 voxels);
// each block is built by one task from the pieces that reach it, so no locks and no merging of trees.
// Voxel centres whose approximate position is within the error bound of a section boundary, of an end
// plane, or of a near tie between two rods are decided by the exact test; so is every voxel near a
// piece whose approximation cannot be bounded (sections folding over in bends tighter than the
// section's radius, cusps, jumps of E), once per voxel.
//
// Cost: memory is bounded before anything is allocated (voxel/diagnostics.hpp estimates it): each
// rod's pieces stop refining at a quarter of the smallest voxel edge and at a per-rod budget
// (rod_pieces.hpp), and the grid holds the active voxels only. Work can be cancelled
// (RasterOptions::wasInterrupted).
#pragma once

#include "geometry/rod.hpp"
#include "voxel/printer_grid.hpp"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <vector>

namespace rodfab::voxel {

// Name of the grid of Young's modulus (MPa) the rasterizer produces and the .vdb files hold.
inline constexpr const char* kModulusGridName = "modulus_mpa";

// Depths of two rods at a voxel that differ by no more than this are equal for the overlap rule.
inline constexpr double kDepthTieTolerance = 1e-9;

namespace detail {
struct RodPieces;
}
template <typename TreeT>
class TreeRecycler;

struct RasterOptions {
  RasterOptions() = default;
  RasterOptions(int threadCount, std::function<bool()> interrupted = {})
      : threads(threadCount), wasInterrupted(std::move(interrupted)) {}

  int threads = 0;  // threads at most; 0 = as many as the calling TBB arena has (all cores from a plain thread)
  // Cancellation, in the style of OpenVDB's interrupters: when set, the rasterizer calls it from its
  // worker threads (so it must be thread-safe, e.g. a read of an atomic flag set by a signal handler)
  // between small units of work, at least every ~20 ms of work per thread on this machine (2 cores),
  // while cutting the rods into pieces (constructor) and while rasterizing. Once it returns true the
  // operation stops within that time and throws voxel::Interrupted; nothing partial is returned.
  std::function<bool()> wasInterrupted;
};

// Thrown when RasterOptions::wasInterrupted returned true.
struct Interrupted : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Rasterization {
  openvdb::FloatGrid::Ptr grid;            // named kModulusGridName, with the printer transform
  std::vector<std::uint64_t> voxelsPerRod; // active voxels each rod won, indexed like the rods
  std::uint64_t exactEvaluations = 0;      // voxels sent to the exact test (borderline cases)
  // Groups of four neighbouring voxels inside a swept piece for sure, some already held by other
  // candidates (crossings, joints), whose overlaps were all settled at once on four lanes rather than
  // voxel by voxel (a count for tests and profiles; it does not depend on the thread count or bands).
  std::uint64_t quadsSettledAtOnce = 0;
};

class Rasterizer {
public:
  // Prepares every rod once (the pieces); `structure` must outlive the rasterizer.
  Rasterizer(const geometry::RodStructure& structure, const PrinterGrid& grid, RasterOptions options = {});
  ~Rasterizer();
  Rasterizer(Rasterizer&&) noexcept;
  Rasterizer& operator=(Rasterizer&&) noexcept;

  // Voxel layers zBegin <= k < zEnd only (clipped to the grid); rods whose bounds miss the band cost
  // next to nothing. A voxel gets the same value whichever band computes it. The returned grid's tree
  // comes back to this rasterizer when its last owner lets it go (while the rasterizer lives), and up
  // to TreeRecycler::kKeptTrees such trees wait to be reused by the next calls (releaseSpareTrees
  // frees them). Calls may run concurrently (the recycler locks); a moved-from Rasterizer may only be
  // destroyed or assigned to.
  Rasterization rasterizeLayers(int zBegin, int zEnd) const;
  // Deletes the let-go trees waiting to be reused, and those let go later: call once streaming is
  // over (later calls still work, allocating afresh). Thread-safe.
  void releaseSpareTrees() const;
  Rasterization rasterize() const { return rasterizeLayers(0, grid_.dims.z()); }

  const PrinterGrid& grid() const { return grid_; }
  std::size_t pieceCount() const;

private:
  Rasterization run(int zBegin, int zEnd) const;
  void checkInterrupt() const;

  const geometry::RodStructure* structure_;
  PrinterGrid grid_;
  RasterOptions options_;
  std::vector<detail::RodPieces> rods_;
  openvdb::CoordBBox partBounds_;
  // The grids' trees come back here when their owners let them go, and later bands are built from
  // their nodes (tree_assembly.hpp): streamed bands allocate leaves for the first bands only.
  std::unique_ptr<TreeRecycler<openvdb::FloatTree>> trees_;
};

// The whole design in one call.
Rasterization rasterize(const geometry::RodStructure& structure, const PrinterGrid& grid, RasterOptions options = {});

}  // namespace rodfab::voxel
