// The design file (`rodfab.design/1`, JSON, millimetres and MPa): its rods, read with full validation,
// and written. The file's "mechanics" and "optimize" blocks belong to mechanics/ (mechanics/mechanics_file.hpp
// reads and writes a design with them); here they are allowed and left unread.
#pragma once

#include "common/located_issues.hpp"

#include "geometry/rod.hpp"

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace rodfab::geometry {

inline constexpr const char* kDesignFormat = "rodfab.design/1";
// The largest Young's modulus a design may give (MPa): 1 TPa, above any printable material and far
// inside the float range the voxel grids store moduli in.
inline constexpr double kMaxModulusMpa = 1e6;
// The smallest (MPa): 1 Pa, softer than any solid that keeps a shape. Below it the solver's stiffness
// lies beneath its rounding (bounds of 1e-300 MPa were taken and failed in Newton without a word why).
inline constexpr double kMinModulusMpa = 1e-6;
// The largest section dimension (diameter, width, height) a design may give, in mm: a kilometre, so
// that stiffnesses (E I grows as the fourth power) and bounding boxes stay finite.
inline constexpr double kMaxSectionMm = 1e6;
// The largest magnitude of a knot value: the solver's parameter arithmetic is exact to 1e15 (a
// cantilever on knots [0, 1e15] gives the [0, 1] answer; on [0, 1e16] a displacement twice too large).
inline constexpr double kMaxKnotMagnitude = 1e12;
// The longest name (of a rod, of a load case) a design may give, in bytes of UTF-8: names are shown in
// messages, reports and file names' neighbourhood, never megabytes of them.
inline constexpr std::size_t kMaxNameBytes = 256;

// One violation: where (a JSON path such as `rods[3].centerline.knots[5]`) and what was expected.
struct DesignIssue {
  std::string path;
  std::string message;
};

// Every violation found in one file (reading does not stop at the first). what() lists them all,
// one per line, as `FILE: PATH: MESSAGE`.
class DesignError : public common::IssueListError<DesignIssue> {
public:
  DesignError(std::string file, std::vector<DesignIssue> issues);
};

// The rods of a design file. Throws DesignError (also for an unreadable file, with path "").
RodStructure readDesign(const std::filesystem::path& file);
// `sourceName` names the text in messages.
RodStructure parseDesign(const std::string& text, const std::string& sourceName);

// Checks `text` as parseDesign does, building every rod, but keeps only what summarize would say of
// the rods: the memory of the rods being built (one a thread) rather than of all of them. For callers
// that check a design they write or pass on (`rodfab rods-from-cad`). Throws as parseDesign.
DesignSummary summarizeDesign(const std::string& text, const std::string& sourceName);
// The same on the document a writer would dump (designToJson's): its text reads back as this document
// (nlohmann writes a double's shortest exact digits), so a writer checks what it writes without
// printing and parsing it. Throws as parseDesign.
DesignSummary summarizeDesignDocument(const nlohmann::ordered_json& document, const std::string& sourceName);
// Keys in the order of the format description (name, centerline, section, frame, caps, modulus).
nlohmann::ordered_json designToJson(const RodStructure& structure, const std::string& description = {});
// One rod per line, so diffs of generated designs stay readable; sealed as rodfab's (its first member
// "written_by", common::sealJsonObject). Written to a temporary name beside
// `file` and renamed (common::writeFileAtomically), so a reader never sees half a file. Writes the
// rods only: a design with mechanics goes through mechanics::writeDesign.
void writeDesign(const RodStructure& structure, const std::filesystem::path& file, const std::string& description = {});

// True when `file` is a regular file that writeDesign (or writeDesignDocument) wrote and nobody has
// changed since: its "written_by" seal (common::sealJsonObject) matches its bytes. What `--output` of a
// command writing designs may replace; a design a person wrote or edited never is.
bool isDesignRodfabWrote(const std::filesystem::path& file);

}  // namespace rodfab::geometry
