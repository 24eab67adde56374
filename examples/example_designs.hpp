// The bundled example designs, modelled on the structures of the published work. They are generated
// here (and written to examples/*.json by rodfab_generate_examples) so they stay reproducible.
#pragma once

#include "geometry/rod.hpp"
#include "mechanics/mechanics_spec.hpp"

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

// A half-cylindrical hexagonal lattice (an arm cast) of rectangular strips, the strips' width
// across the surface; stiff along the cast's rim, softer over its crown where it is flattened.
geometry::RodStructure armCast();

// ---- Training cases: each a design's mechanics block (supports, loads, load steps), the
// deformation of the published shape-memory training, on the uniform design (before any modulus
// optimization). Attach one with `design.mechanics = ...Training(...)`.

// The box net folded up by forces on the outer edges of its four outer squares, perpendicular to
// those edges (inwards and upwards at 45 degrees, `force` N each at the edge's middle), the middle
// square clamped at its corners. The hinges end on the squares' edges: T-joints.
mechanics::MechanicsSpec unfoldingBoxTraining(double force = 0.03);

// The spring compressed by `compression` (a fraction of its height) through prescribed
// displacements at four equidistant nodes of its top ring (pinned), the bottom ring's nodes clamped.
mechanics::MechanicsSpec bucklingSpringTraining(const SpringParameters& parameters = {}, double compression = 0.15);

// The cast flattened: the rod ends on its two rims (pinned) moved to where unrolling the half
// cylinder onto the plane tangent to its crown puts them (`fraction` of the way there).
mechanics::MechanicsSpec armCastTraining(double fraction = 1.0);

}  // namespace rodfab::examples
