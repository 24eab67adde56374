// calibration/: DMA data, the modulus-to-Vero-fraction fit and its inverse, the floor, calibration
// files and fit plots. materials/ queries a loaded Calibration (const, thread-safe, allocation-free).
#pragma once

#include "calibration/calibration_file.hpp"
#include "calibration/data.hpp"
#include "calibration/fit.hpp"
#include "calibration/model.hpp"
#include "calibration/plot.hpp"
