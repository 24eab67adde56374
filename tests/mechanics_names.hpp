// The names the mechanics tests of joints (tests/test_mechanics_joints.cpp, test_mechanics_star.cpp) use
// unqualified: rodfab's namespaces, the design's types and the fixture's places on rods. Include it in a
// test's .cpp only, after its other headers; names a test needs beyond these it declares itself.
#pragma once

#include "tests/mechanics_fixture.hpp"

#include "geometry/geometry.hpp"
#include "mechanics/mechanics.hpp"

using namespace rodfab;
using geometry::Section;
using geometry::Vec3;
using mechanics::Design;
using mechanics::RodEnd;
using mechanics::StaticProblem;
using test::at;
using test::atPoint;
using test::straight;
