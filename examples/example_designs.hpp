// The bundled example designs, modelled on the structures of the published work. They are generated
// here (and written to examples/*.json by rodfab_generate_examples) so they stay reproducible.
#pragma once

#include "geometry/rod.hpp"
#include "mechanics/mechanics_spec.hpp"

#include <string>
#include <vector>

namespace rodfab::examples {

// A flat, cross-shaped net of 6 square frames (34 rods): 24 stiff frame edges whose modulus drops
// towards the corners, and 10 short, soft hinge rods (elliptic sections, at the floor modulus)
// bridging the gaps between neighbouring squares. Printed flat, trained into a box.
geometry::RodStructure unfoldingBox();

// A cylindrical lattice of 312 curved rods: 288 helical struts between the nodes of a diamond
// pattern plus 24 ring arcs closing the top and bottom. E varies along the height, softest at
// mid-height where the spring should buckle.
struct SpringParameters {
  double radius = 15.0;        // mm, lattice cylinder
  double height = 32.0;        // mm, bottom to top ring
  int nodesAround = 12;
  int levels = 12;
  double rodDiameter = 0.8;    // mm
  double modulusEnds = 120.0;  // MPa, top and bottom
  double modulusMiddle = 8.0;  // MPa, mid-height (the 8 MPa floor)
};
geometry::RodStructure bucklingSpring(const SpringParameters& parameters = {});

// The buckling spring scaled to fill `envelopeMm` (e.g. 84.6 x 84.6 x 90 mm: 2000 x 1000 x 3000
// Connex3 voxels): geometry scaled by the largest factor that fits, rod diameter as given.
geometry::RodStructure bucklingSpringScaledTo(const geometry::Vec3& envelopeMm, double rodDiameterMm = 1.2);

// ---- Benchmark designs (not bundled: remade exactly by rodfab_generate_examples --benchmark CLASS).

// A cubic lattice of round rods between the nodes of a nodes.x x nodes.y x nodes.z grid: one rod per
// edge between neighbouring nodes ((nx-1) ny nz + nx (ny-1) nz + nx ny (nz-1) rods, named along the
// x, y and z edges in turn), round caps, every rod ending at the nodes it joins (joints of up to 6
// rods). `bow` = 0: straight rods. `bow` > 0: each rod bowed sideways, its middle displaced by `bow`
// times the node spacing in the direction of the next axis (x -> y -> z -> x), the sign alternating
// with the parity of the rod's first node (a cubic through four samples of a half sine wave). E along
// each rod: 8 MPa at mid-height of the envelope rising quadratically to 120 MPa at the top and bottom
// (three-point piecewise linear in the rod parameter, so rods at a node agree there).
// Scaled (each axis on its own; the rods' diameter as given) so the solid fills `envelopeMm`
// exactly: RodStructure::bounds() is [0, envelope] up to its sampling pad (< 1 um).
struct LatticeParameters {
  Eigen::Vector3i nodes{8, 8, 9};
  double rodDiameter = 1.5;  // mm
  double bow = 0.0;          // fraction of the node spacing
};
geometry::RodStructure cubicLatticeScaledTo(const geometry::Vec3& envelopeMm, const LatticeParameters& parameters = {});

// A solid block filling [0, size]: one straight rod along x, size.x() long, with a size.y() x size.z()
// rectangular section and flat caps, E rising linearly from 8 to 190 MPa along x. At the Connex3 voxel
// 84.6 x 84.6 x 9 mm is 2000 x 1000 x 300 voxels, every one printed.
geometry::RodStructure denseBlock(const geometry::Vec3& sizeMm = {84.6, 84.6, 9.0});

// The benchmark classes by name: "spring" (bucklingSpringScaledTo, 312 curved rods, 1.2 mm),
// "lattice" (1,520 straight 1.5 mm rods, 8 x 8 x 9 nodes), "curved-lattice" (the same bowed by 0.15
// of the spacing), all three filling 84.6 x 84.6 x 90 mm (2000 x 1000 x 3000 Connex3 voxels); and
// "dense" (denseBlock()). Throws std::invalid_argument for another name.
std::vector<std::string> benchmarkClasses();
geometry::RodStructure benchmarkDesign(const std::string& name);

// A half-cylindrical hexagonal lattice (an arm cast) of rectangular strips, the strips' width
// across the surface; stiff along the cast's rim (120 MPa), softer over its crown (39 MPa).
geometry::RodStructure armCast();

// ---- Training cases: each a design's mechanics block (supports, loads, load steps), the
// deformation of the published shape-memory training, on the uniform design (before any modulus
// optimization). Attach one with `design.mechanics = ...Training(...)`.

// The box net folded up by forces on the outer edges of its four outer squares, perpendicular to
// those edges as in the published training (`force` N each at the edge's middle, normal to the
// square): follower loads, turning with the edge's cross-section as the square folds, so each
// keeps bending its hinges the same way (a dead load past 90 degrees would open them again). The
// middle square is clamped at its corners. The hinges end on the squares' edges: T-joints.
mechanics::MechanicsSpec unfoldingBoxTraining(double force = 0.03);

// The spring compressed by `compression` (a fraction of its height) through prescribed
// displacements at four equidistant nodes of its top ring (pinned), the bottom ring's nodes clamped:
// the published training ("a prescribed displacement on the top of the structure at four
// equidistant locations").
mechanics::MechanicsSpec bucklingSpringTraining(const SpringParameters& parameters = {}, double compression = 0.15);

// The same compression applied uniformly: every node of the top ring pinned and moved down alike
// (the published target's "uniform compression of the structure").
mechanics::MechanicsSpec bucklingSpringUniformCompression(const SpringParameters& parameters = {}, double compression = 0.15);

// The cast flattened: the rod ends on its two rims clamped, moved to where unrolling the half
// cylinder onto the plane tangent to its crown puts them and turned a quarter turn about the cast's
// axis so the strips lie in that plane (`fraction` of the way there), as hands hold it flat.
mechanics::MechanicsSpec armCastTraining(double fraction = 1.0);

// ---- Training targets: the shape each training case should produce (the published target), as a
// load case {supports and loads of the training case above, target rods} for `rodfab optimize`.
// The box's and the cast's are derived from geometry alone (rigid folds, an unrolling); the
// spring's is a mechanical equilibrium (below). Every rod of the design has a target; the target
// rods are in name order.

// The net folded into a closed box: the four squares next to the middle one turn up by 90 degrees
// and the lid (beyond the back wall) by another 90, each gap's hinge rods bending into a quarter
// circle of their own length (radius 2 gap / pi), the squares rigid.
mechanics::LoadCase unfoldingBoxFold(double force = 0.03);

// The spring's training (bucklingSpringTraining: four top nodes pushed down) with, as target, the
// equilibrium of the graded spring (bucklingSpring(parameters), its own E) under the uniform
// compression (bucklingSpringUniformCompression): "a uniform compression of the structure,
// resulting in buckling of the curved rods at the vertical center". Simulated with the mechanics
// solver as `rodfab simulate` does with its defaults (degree 6, automatic spans, error estimate
// below 1e-4 or std::runtime_error); each target rod is the solved centerline and orientation.
// A geometric map (z scaled, a radial bulge) is not used: it turns the rods at every joint, which
// rigid joints cannot follow (optimize/README.md). Deterministic: the solver's result does not
// depend on the thread count. Takes a few seconds (one simulation of 36,624 unknowns).
mechanics::LoadCase bucklingSpringCompression(const SpringParameters& parameters = {}, double compression = 0.15);

// The cast unrolled onto the plane tangent to its crown (z = R): the point at arc length s from the
// rim at angle 0 and axial position x goes to (x, R pi / 2 - s, R), the strips' normal to +z. An
// isometry: every strip keeps its length and becomes straight.
mechanics::LoadCase armCastFlattened();

}  // namespace rodfab::examples
