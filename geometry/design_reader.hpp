// Building blocks for stages that read their own blocks of the design file (mechanics/ reads
// "mechanics" and "optimize"): the strictly parsed document with its rods, and the checks that
// collect every violation at its JSON path. Most code wants geometry/design_file.hpp instead.
#pragma once

#include "common/json_input.hpp"
#include "geometry/design_file.hpp"

#include <nlohmann/json.hpp>

#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace rodfab::geometry {

// `j` as it appears in messages: common::describeJson, except that a number beyond the range of a
// double is named as written.
std::string describe(const nlohmann::json& j);
// JSON paths: `path[i]` and `path.key` (just `key` at the top level).
using common::indexPath;
using common::memberPath;

// The rod names of a design, each with the JSON path of the rod that carries it.
using RodNames = std::map<std::string, std::string>;

// A rod as the design file gives it, checked, before its centerline is sampled: Rod's constructor's
// arguments (building the Rod is most of the work of reading a design).
struct RodParts {
  std::string name;
  NurbsCurve centerline;
  Section section;
  std::optional<Vec3> referenceNormal;
  std::optional<QuaternionSpline> orientation;
  CapStyle caps = CapStyle::Round;
  BSplineField modulus;
};

// Collects every violation of one file. Each check returns what it could read (std::nullopt after
// recording an issue), so later checks go on and one read reports everything. Not thread-safe.
class DesignReader {
public:
  std::vector<DesignIssue> issues;

  void fail(const std::string& path, const std::string& message);
  // An issue for every key of `obj` outside `allowed`.
  void onlyKeys(const nlohmann::json& obj, const std::string& path, const std::set<std::string>& allowed);
  // obj[key], or nullptr after an issue "missing; expected `what`".
  const nlohmann::json* require(const nlohmann::json& obj, const std::string& path, const std::string& key,
                                const std::string& what);

  std::optional<double> number(const nlohmann::json& j, const std::string& path, const std::string& what);
  std::optional<double> positive(const nlohmann::json& j, const std::string& path, const std::string& what);
  // A section's diameter, width or height in mm: > 0 and at most kMaxSectionMm.
  std::optional<double> sectionSize(const nlohmann::json& j, const std::string& path, const std::string& what);
  std::optional<int> degree(const nlohmann::json& j, const std::string& path);  // 1..kMaxDegree
  std::optional<Vec3> vector3(const nlohmann::json& j, const std::string& path, const std::string& what);
  // A rotation [w, x, y, z], not normalized but not zero.
  std::optional<Eigen::Vector4d> quaternion(const nlohmann::json& j, const std::string& path);
  std::optional<std::string> string(const nlohmann::json& j, const std::string& path, const std::string& what);
  // A name (a rod's, a load case's; `what`: "a rod name"): a string of 1 to kMaxNameBytes bytes without
  // control characters (names reach messages and the terminal).
  std::optional<std::string> name(const nlohmann::json& j, const std::string& path, const std::string& what);
  // A knot vector for `count` control values of degree `p` (either may be unknown: then only the
  // entries are checked).
  std::optional<std::vector<double>> knots(const nlohmann::json& j, const std::string& path, std::optional<int> p,
                                           std::optional<std::size_t> count);
  // A Young's modulus in MPa: > 0 and at most kMaxModulusMpa (grids store moduli as floats).
  std::optional<double> youngsModulus(const nlohmann::json& j, const std::string& path);

  // A NURBS centerline {degree, knots, points, weights}, coordinates in mm, of finite non-zero length
  // unless `length` is LeftToRod: a rod's centerline, whose length the Rod computes and checks itself
  // (CenterlineError) while it is built on the reader's threads, rather than a second time here.
  enum class CenterlineLength { Checked, LeftToRod };
  std::optional<NurbsCurve> centerline(const nlohmann::json& j, const std::string& path,
                                       CenterlineLength length = CenterlineLength::Checked);
  std::optional<Section> section(const nlohmann::json& j, const std::string& path);
  // {degree, knots, quaternions}; with `curve`, its domain must equal the curve's.
  std::optional<QuaternionSpline> orientation(const nlohmann::json& j, const std::string& path, const NurbsCurve* curve);
  // A reference normal: finite, not zero and, when the centerline is known, not parallel to its
  // tangent at the start (the frame is built from there).
  std::optional<Vec3> referenceNormal(const nlohmann::json& j, const std::string& path, const NurbsCurve* curve);
  // A constant (MPa) or a B-spline {degree, knots, values} over `curve`'s domain (nullopt without a curve).
  std::optional<BSplineField> modulus(const nlohmann::json& j, const std::string& path, const NurbsCurve* curve);
  // One rod of "rods", checked but not built; its name joins `names` (a repeated name is an issue).
  std::optional<RodParts> rod(const nlohmann::json& j, const std::string& path, RodNames& names);
};

// What reading keeps of the rods it builds: the rods themselves, or only their summary (a reader that
// checks a design without using its rods needs the memory of the rods being built, not of all).
enum class RodsKept { All, SummaryOnly };

// A design file as geometry reads it: the document, the rods that read without issue (none kept with
// RodsKept::SummaryOnly) and their summary, and the names of all rods. The blocks of higher stages
// ("mechanics", "optimize") are left in `json`, unread, for their readers.
struct DesignDocument {
  nlohmann::json json;
  RodStructure structure;
  DesignSummary summary;  // of the rods that read without issue, in the file's order
  RodNames rodNames;
  bool rodsListed = false;  // "rods" is a non-empty array (blocks that name rods are read only then)
};

// Parses `text` (named `sourceName` in messages) and checks the format, units, description and
// rods, recording issues in `reader`. Throws DesignError at once when the text is not JSON or not
// an object, common::OutOfMemory (naming `sourceName`) before parsing when the document would take
// more than the memory budget (about 24 bytes per byte of text). The top-level keys allowed are those of the whole format, the higher stages' blocks
// included.
DesignDocument parseDesignDocument(const std::string& text, const std::string& sourceName, DesignReader& reader,
                                   RodsKept kept = RodsKept::All);
// The same on a document already parsed (the checks after the JSON text's own: no memory estimate).
DesignDocument readDesignDocument(nlohmann::json document, const std::string& sourceName, DesignReader& reader,
                                  RodsKept kept = RodsKept::All);

// The bytes of a design file (bounded by common::kMaxJsonBytes); throws DesignError(file, path "")
// when it cannot be read.
std::string readDesignText(const std::filesystem::path& file);

}  // namespace rodfab::geometry
