// Building blocks for stages that write their own blocks of the design file (mechanics/ writes
// "mechanics" and "optimize"): the JSON of curves and vectors as the format gives them, and the
// file's layout. Most code wants geometry/design_file.hpp instead.
#pragma once

#include "geometry/design_file.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>

namespace rodfab::geometry {

nlohmann::ordered_json vec3Json(const Vec3& v);                              // [x, y, z]
nlohmann::ordered_json nurbsJson(const NurbsCurve& curve);                   // {degree, knots, points, weights}
nlohmann::ordered_json quaternionSplineJson(const QuaternionSpline& spline);  // {degree, knots, quaternions}

// One rod of "rods", from what Rod's constructor takes: what designToJson writes for the Rod built from
// the same arguments, for writers that need not sample a centerline (the CAD reader). Not checked here.
nlohmann::ordered_json rodJson(const std::string& name, const NurbsCurve& centerline, const Section& section,
                               const std::optional<Vec3>& referenceNormal, const std::optional<QuaternionSpline>& orientation,
                               CapStyle caps, const BSplineField& modulus);
// A design document around `rods` (an array of rodJson): what designToJson makes of them.
nlohmann::ordered_json designJson(nlohmann::ordered_json rods, const std::string& description = {});

// Writes `doc` (a design as designToJson makes it, with any blocks of higher stages added) in the
// file's layout: every top-level key but "rods" and "mechanics" on a line of its own, then one rod
// per line, then the "mechanics" block indented, all after the "written_by" seal (isDesignRodfabWrote).
// Atomic as writeDesign.
void writeDesignDocument(const nlohmann::ordered_json& doc, const std::filesystem::path& file);

}  // namespace rodfab::geometry
