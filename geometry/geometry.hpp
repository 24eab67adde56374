// geometry/: the rod design model. NURBS centerlines, frames, sections, E(s), the design file.
#pragma once

#include "geometry/design_file.hpp"
#include "geometry/frame.hpp"
#include "geometry/nurbs.hpp"
#include "geometry/rod.hpp"
#include "geometry/section.hpp"
