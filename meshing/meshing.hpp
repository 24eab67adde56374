// meshing/: rod structures from shapes. A triangle mesh becomes the dual of its simplified version,
// laid on the original surface (`rodsFromMesh`); a CAD curve network becomes one rod per edge curve
// with its exact NURBS (`rodsFromCad`). Both return an ordinary geometry::RodStructure, which
// geometry::writeDesign writes as a rodfab.design/1 file.
//
// Units: millimetres (a mesh's or CAD file's coordinates are taken as mm) and MPa.
// Errors: MeshError for every problem with an input file; what() starts with the file's name and says
// what is wrong and where (a face number, a coordinate). std::invalid_argument for options out of the
// ranges below (the CLI checks them first). common::OutOfMemory when the input would need more memory
// than the process's budget (estimated from the file's size before it is read); common::Interrupted
// when SIGINT/SIGTERM arrives (work polls common::interruptRequested()).
// Thread safety: the functions are reentrant; they use TBB's current arena for per-rod work, and the
// result does not depend on the number of threads.
#pragma once

#include "geometry/rod.hpp"

#include <cstddef>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::meshing {

// A problem with an input file. what() is "FILE: MESSAGE".
class MeshError : public std::runtime_error {
public:
  MeshError(const std::filesystem::path& file, const std::string& message);
  const std::filesystem::path& file() const { return file_; }

private:
  std::filesystem::path file_;
};

// Ranges of the options (inclusive).
inline constexpr int kMinFaces = 4, kMaxFaces = 100000;
inline constexpr int kMinSubdivisions = 2, kMaxSubdivisions = 64;
// Mesh files larger than this are refused before reading (a 2 GiB binary STL holds 43 million triangles).
inline constexpr std::uintmax_t kMaxMeshFileBytes = std::uintmax_t(2) << 30;

struct MeshRodOptions {
  // Faces of the simplified mesh, kMinFaces..kMaxFaces and at most the input's face count. A closed
  // mesh of F faces gives F nodes and 3F/2 rods.
  int faces = 200;
  // Points sampled along each dual edge between its two nodes (kMinSubdivisions..kMaxSubdivisions),
  // projected onto the original surface and interpolated. Doubled per rod (up to 16 times as many)
  // while the centerline leaves the surface by more than surfaceTolerance; of the fits tried, the
  // closest to the surface that bends no tighter than the section's bounding radius is kept (or, if
  // all do, the gentlest).
  int subdivisions = 4;
  // Largest distance (mm, > 0) of the centerline from the original surface, checked at 16 points per
  // knot span of every rod. The report says when a rod still exceeds it after refinement.
  double surfaceTolerance = 0.05;
  // Each rod's section (its frame's d1 is the surface normal, so `width` is the rod's thickness normal
  // to the surface and `height` its breadth within the tangent plane), caps and constant E (MPa, > 0).
  geometry::Section section = geometry::Section::circle(1.0);
  geometry::CapStyle caps = geometry::CapStyle::Round;
  double modulusMpa = 120.0;
};

struct MeshRodReport {
  std::size_t inputVertices = 0, inputFaces = 0;  // after welding duplicate vertices
  std::size_t weldedVertices = 0;                 // vertices removed by welding (STL repeats every corner)
  std::size_t simplifiedVertices = 0, simplifiedFaces = 0;
  // The faces asked for (MeshRodOptions::faces). The simplification stops above them where every
  // further collapse would turn a face's normal over (a plate thinner than its triangles are wide).
  std::size_t requestedFaces = 0;
  std::size_t nodes = 0, rods = 0;
  std::size_t boundaryEdges = 0;   // edges of the simplified mesh with one face: no rod crosses them
  std::size_t components = 0;      // connected parts of the rod structure (1 for a connected mesh)
  std::size_t refinedRods = 0;     // rods that needed more samples than `subdivisions` to meet the tolerance
  std::size_t rodsAboveTolerance = 0;
  // Of those, rods whose closer fits bent tighter than the section's bounding radius (they follow a
  // creased surface's facets): the gentler fit is kept.
  std::size_t rodsHeldOffCreases = 0;
  double largestSurfaceDistance = 0.0;  // mm, over the checked centerline points of every rod
  // Smallest radius of curvature of any centerline (mm; infinite when all are straight), at the same points.
  double smallestBendRadius = std::numeric_limits<double>::infinity();
  // Rods bent somewhere tighter than their section's bounding radius: the section may fold over itself on
  // the inside of the bend (thick rods on a fine mesh); the slicer also tests such voxels the slow way.
  std::size_t rodsBentTighterThanSection = 0;
  double readSeconds = 0.0, simplifySeconds = 0.0, rodSeconds = 0.0;
};

struct MeshRods {
  geometry::RodStructure structure;  // rods named "rod-<i>" in the order of their mesh edges (sorted by vertex)
  MeshRodReport report;
};

// Reads `meshFile` (.stl binary or ASCII, .obj, .ply, .off; the extension decides, in any letter
// case), welds identical vertices, simplifies it to about `options.faces` triangles (CGAL's
// Garland-Heckbert edge collapse: see meshing/README.md), and returns the rods of its dual laid on the
// original surface:
//  - a node per simplified face: its centroid moved to the closest point of the original surface;
//    every rod ending at a node ends exactly there, so `simulate` joins them;
//  - a rod per interior edge, from one face's node to the other's along the shortest path over the two
//    faces (crossing the edge within its middle half): `subdivisions` points along that path are moved
//    to the original surface, and a cubic NURBS
//    interpolates the node, the points and the other node (chord-length parameters on [0, 1]);
//  - boundary edges of an open mesh give no rod (their faces' nodes have fewer than 3 rods);
//  - the frame's reference normal is the original surface's normal at the rod's first node (the
//    simplified face's, or an axis made perpendicular, where those lie along the rod).
// Polygons with more than 3 corners are split into a fan of triangles from their first corner.
// Throws MeshError when the file is unreadable, empty or not a mesh, has non-finite coordinates, a
// degenerate face (two corners at one point, or zero area), an edge of more than two faces or a vertex
// where separate sheets meet (non-manifold), or fewer faces than asked for; the message names the face
// or the point. std::invalid_argument for options outside their ranges.
MeshRods rodsFromMesh(const std::filesystem::path& meshFile, const MeshRodOptions& options);

// The mesh reader alone, on bytes in memory (`format`: "stl", "obj", "ply" or "off"), for the fuzz
// target and tests: the vertex and face counts after welding. Throws MeshError naming `sourceName`.
struct MeshCounts {
  std::size_t vertices = 0, faces = 0;
};
MeshCounts checkMeshBytes(const std::string& bytes, const std::string& format, const std::string& sourceName);

struct CadRodOptions {
  geometry::Section section = geometry::Section::circle(1.0);
  geometry::CapStyle caps = geometry::CapStyle::Round;
  double modulusMpa = 120.0;
  // Curve ends closer than this (mm, > 0) become one joint: they are moved to their common mean so the
  // rods end at exactly the same point. Ends chain (a within it of b, b of c), and a chain wider than
  // this is refused: no end is moved by more than the tolerance.
  double jointTolerance = 1e-3;
};

// How closely a curve whose exact B-spline needs a degree above geometry::kMaxDegree is approximated
// (mm): far below any printer's voxel (0.03 mm and more), and below rodfab's finest sampling (1e-4 mm).
inline constexpr double kCadApproximationToleranceMm = 1e-5;

struct CadRodReport {
  std::size_t edges = 0;          // distinct edges in the model (an edge shared by faces counts once)
  std::size_t rods = 0;
  std::size_t joints = 0;         // points where two or more rod ends meet
  std::size_t skippedDegenerate = 0;  // edges without a curve (seams of degenerate faces, zero length)
  double largestEndMove = 0.0;    // mm: how far merging moved a curve end
  std::size_t approximated = 0;   // curves of a degree above kMaxDegree (offset curves, high-degree splines)
  double largestApproximationError = 0.0;  // mm: the farthest such a curve's rod strays from it (OpenCASCADE's measure)
  // As MeshRodReport's: the smallest radius of curvature of any rod (mm, infinite when all are straight;
  // corners between spans are joints, not bends) and the rods bent tighter than the section's bounding radius.
  double smallestBendRadius = std::numeric_limits<double>::infinity();
  std::size_t rodsBentTighterThanSection = 0;
  // Entities OpenCASCADE could not convert to shapes, left out of the design with every curve they
  // hold (a curve set with one unconvertible curve loses all of its curves; a curve of a set it made
  // no edge of, such as a circle of negative radius, is left out alone; an IGES composite curve loses
  // the members its reader left out), and the first of them in the model's order named ("entity #15
  // (GEOMETRIC_CURVE_SET): ...", "entity D9 (...)"). rods-from-cad warns of them.
  std::size_t untranslated = 0;
  std::string firstUntranslated;
};

struct CadRods {
  geometry::RodStructure structure;  // rods named "edge-<i>" in the model's edge order
  CadRodReport report;
};

// Reads a STEP (.step, .stp) or IGES (.iges, .igs) file with OpenCASCADE and turns every edge curve of
// the model into a rod with its exact NURBS (lines, circles and conics converted to B-splines),
// trimmed to the edge's parameter range. A curve whose B-spline would need a degree above
// geometry::kMaxDegree (an offset curve, a spline of degree 8 to 25 from some CAD systems) is
// approximated by one of degree kMaxDegree, as smooth as the curve up to C2, within
// kCadApproximationToleranceMm (the report counts them). Throws MeshError when the file cannot be
// read, is malformed (meshing/README.md: what is checked before OpenCASCADE reads and transfers it),
// holds no edge curve (naming the first entity OpenCASCADE could not convert, if any), a curve cannot be
// approximated so closely, curve ends chain into a joint wider than the joint tolerance (naming its two
// ends farthest apart), or a rod would not pass the design
// file's checks (coordinates beyond +-1e9 mm, zero length, a centerline too intricate to sample): the
// structure returned is always one `rodfab validate` accepts.
CadRods rodsFromCad(const std::filesystem::path& cadFile, const CadRodOptions& options);

// rodsFromCad's design written to `designFile` (geometry::writeDesignDocument, atomic; `description`
// its "description", empty for none) instead of kept: the file writeDesign(rodsFromCad(...).structure,
// designFile, description) writes, checked the same way, but every rod is built once and let go, so
// the memory peaks at the design's document rather than at its rods (meshing/README.md, "Memory").
// Returns the report and what geometry::summarize says of the rods. Throws as rodsFromCad and as
// writeDesignDocument; nothing is written when it throws.
struct CadDesignWritten {
  CadRodReport report;
  geometry::DesignSummary summary;
};
CadDesignWritten writeDesignFromCad(const std::filesystem::path& cadFile, const CadRodOptions& options,
                                    const std::filesystem::path& designFile, const std::string& description);

}  // namespace rodfab::meshing
