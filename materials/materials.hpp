// materials/: from Young's modulus to one material per voxel. Vero fractions from a calibration,
// ditherers (white noise, blue-noise mask, 3D error diffusion) and measured dither quality.
#pragma once

#include "materials/blue_noise_mask.hpp"
#include "materials/dither_quality.hpp"
#include "materials/ditherer.hpp"
#include "materials/fraction_map.hpp"
#include "materials/sample_regions.hpp"
