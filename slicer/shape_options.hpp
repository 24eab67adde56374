// Options shared by the commands that make designs from shapes (rods-from-mesh, rods-from-cad).
#pragma once

#include "geometry/rod.hpp"
#include "slicer/options.hpp"

#include <optional>
#include <string>

namespace rodfab::cli {

// Adds --section, --breadth, --modulus, --caps and --profile (the tray the result is checked against).
// `diameterHelp` explains --diameter, which the command adds itself (required).
void addRodShapeOptions(po::options_description& options);

struct RodShape {
  geometry::Section section;
  geometry::CapStyle caps = geometry::CapStyle::Round;
  double modulusMpa = 0;
};

// The section (circle of --diameter; ellipse or rectangle of --diameter along the frame's d1 and
// --breadth along d2), caps and modulus; nullopt after a usage error naming the option.
std::optional<RodShape> parseRodShape(const std::string& command, const po::variables_map& vm);

// The tray size (mm) and name of the profile `nameOrPath` (the --profile value); false after printing
// the error when it cannot be loaded. warnTrayOverhang prints a warning on stderr for every axis where
// the rods' bounding box is larger than the tray.
bool loadTrayProfile(const std::string& command, const std::string& nameOrPath, std::array<double, 3>& trayMm, std::string& name);
void warnTrayOverhang(const geometry::Box3& rodBounds, const std::array<double, 3>& trayMm, const std::string& profile);

// Warns on stderr when the rods are on average shorter than `section` is wide: then each overlaps its
// neighbours along most of its length, the design prints as a lump and every voxel is reached by many
// rods (slow to slice); most often the model was drawn in other units than mm.
void warnThickRods(const geometry::DesignSummary& rods, const geometry::Section& section);

}  // namespace rodfab::cli
