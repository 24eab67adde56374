// voxel/: rod structures rasterized into sparse OpenVDB grids at printer resolution.
#pragma once

#include "voxel/diagnostics.hpp"
#include "voxel/grid_statistics.hpp"
#include "voxel/memory_estimate.hpp"
#include "voxel/printer_grid.hpp"
#include "voxel/rasterize.hpp"
#include "voxel/tree_assembly.hpp"
#include "voxel/vdb_file.hpp"
