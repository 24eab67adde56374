// The values commands read from an option's text, each with its unit in its name: lists of Vero
// fractions, sizes in millimetres and sizes in voxels (both written AxBxC, so the name says which),
// a voxel's size in millimetres (X,Y,Z) and a pair of materials (RIGID,RUBBERY).
// One parser per kind of value, so every command accepts and refuses the same text the same way.
#pragma once

#include <array>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::cli {

// A value that cannot be used; what() starts with the option ("--size: ...") and says what was
// expected. Commands report it as a usage error (exit kUsage).
struct BadValue : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// "0,0.3,1", or a progression "0,0.1,...,1" (the two values before "..." give the step, the one after
// it the last value). Each a Vero fraction in [0, 1]; at least one and at most `maxCount`; no value
// twice (as floats: the grids hold floats). `option` ("--fractions") names the option in messages.
std::vector<double> parseFractionList(const std::string& option, const std::string& text, std::size_t maxCount);

// "30x5x1.5" -> {30, 5, 1.5}: three positive millimetre lengths along x, y, z (LENGTHxWIDTHxHEIGHT).
std::array<double, 3> parseSizeMm(const std::string& option, const std::string& text);

// "128x64x180" -> {128, 64, 180}: three whole voxel counts along x, y, z, each in [1, maxSide].
std::array<int, 3> parseSizeVoxels(const std::string& option, const std::string& text, int maxSide);

// "0.0423,0.0846,0.030" -> {0.0423, 0.0846, 0.030}: a voxel's size in mm along x, y, z (z the build
// direction), each from 0.001 (finer than any printer) to 10 (coarser than any rod worth printing).
std::array<double, 3> parseVoxelSizeMm(const std::string& option, const std::string& text);

// "VeroUltraWhite,Agilus30Black" -> {"VeroUltraWhite", "Agilus30Black"}: the rigid and the rubbery
// material, two different non-empty names without a comma in them.
std::array<std::string, 2> parseMaterialPair(const std::string& option, const std::string& text);

// A number as the messages print it: up to 10 significant digits, no trailing zeros ("%.10g").
std::string formatNumber(double v);

}  // namespace rodfab::cli
