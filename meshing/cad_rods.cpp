// CAD curve networks to rods with OpenCASCADE: every edge's curve, converted to its exact B-spline.
// Built into the CAD reader process (rodfab-cad-reader, cad_reader_main.cpp), which rodsFromCad
// (cad_process.cpp) runs for each file.
#include "common/interrupt.hpp"
#include "common/quoted_text.hpp"
#include "geometry/design_reader.hpp"
#include "geometry/design_writer.hpp"
#include "meshing/cad_checks.hpp"
#include "meshing/cad_reader.hpp"
#include "meshing/input_file.hpp"
#include "meshing/mesh.hpp"

#include <BRep_Tool.hxx>
#include <GeomConvert.hxx>
#include <GeomConvert_ApproxCurve.hxx>
#include <Geom_BSplineCurve.hxx>
#include <Geom_TrimmedCurve.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <IGESControl_Reader.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <STEPControl_Reader.hxx>
#include <Standard_Failure.hxx>
#include <TopExp.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Edge.hxx>
#include <XSControl_TransferReader.hxx>
#include <XSControl_WorkSession.hxx>
#include <gp_Pnt.hxx>

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::meshing {

namespace {

using detail::formatPoint;
using geometry::Vec3;

// OpenCASCADE's readers report to a process-wide messenger (stdout by default): keep it quiet, and
// read one file at a time (the readers share static tables).
std::mutex& readerMutex() {
  static std::mutex m;
  return m;
}

bool isStep(const std::filesystem::path& file) {
  const std::string ext = detail::lowerCaseExtension(file);
  return ext == ".step" || ext == ".stp";
}

// Loads the file, checks what OpenCASCADE would trip over (cad_checks.hpp), then transfers it.
TopoDS_Shape readShape(XSControl_Reader& reader, const std::filesystem::path& file) {
  const std::string format = isStep(file) ? "STEP" : "IGES";
  if (isStep(file)) detail::prescanStepText(file);
  else detail::prescanIgesText(file);
  if (reader.ReadFile(file.c_str()) != IFSelect_RetDone) throw MeshError(file, "not a readable " + format + " file");
  if (reader.NbRootsForTransfer() == 0) throw MeshError(file, "not a readable " + format + " file: it holds no model");
  detail::checkLoadedModel(reader, file);
  try {
    reader.TransferRoots();
  } catch (const Standard_Failure& e) {
    throw MeshError(file, "cannot convert the " + format + " model to shapes: " + e.GetMessageString());
  }
  return reader.OneShape();
}

// "edge 3", with the entity it came from when the transfer recorded one.
std::string edgeName(const XSControl_Reader& reader, const TopoDS_Shape& edge, int index) {
  std::string name = "edge " + std::to_string(index);
  const Handle(XSControl_TransferReader) transfer = reader.WS()->TransferReader();
  if (transfer.IsNull()) return name;
  Handle(Standard_Transient) entity = transfer->EntityFromShapeResult(edge, 1);
  if (entity.IsNull()) entity = transfer->EntityFromShapeResult(edge, 3);
  return entity.IsNull() ? name : name + " (entity " + detail::entityName(reader.Model(), entity) + ")";
}

// An edge of the transferred shape, named in messages only when one is needed (finding its entity
// searches the transfer's records).
struct EdgeRef {
  const XSControl_Reader& reader;
  const TopoDS_Shape& edge;
  int index;
  std::string name() const { return edgeName(reader, edge, index); }
};

geometry::NurbsCurve toNurbs(const Geom_BSplineCurve& bs, const std::filesystem::path& file, const EdgeRef& edge) {
  if (bs.Degree() > geometry::kMaxDegree)
    throw MeshError(file, edge.name() + ": a curve of degree " + std::to_string(bs.Degree()) + ", above the " +
                              std::to_string(geometry::kMaxDegree) + " rodfab supports");
  std::vector<double> knots;
  TColStd_Array1OfReal flat(1, bs.NbPoles() + bs.Degree() + 1);
  bs.KnotSequence(flat);
  for (int i = flat.Lower(); i <= flat.Upper(); ++i) knots.push_back(flat(i));
  std::vector<Vec3> points;
  std::vector<double> weights;
  for (int i = 1; i <= bs.NbPoles(); ++i) {
    const gp_Pnt p = bs.Pole(i);
    // Checked here, not only with the whole design: an untrimmed line of a hostile file is one of
    // thousands, and the first one found ends the work.
    if (!(p.XYZ().Modulus() <= geometry::kMaxCoordinateMm))
      throw MeshError(file, edge.name() + ": a control point at " + detail::formatPoint(p) + " mm, beyond the +-1e9 mm a design allows " +
                                "(an unbounded curve, or a wrong unit?)");
    points.emplace_back(p.X(), p.Y(), p.Z());
    weights.push_back(bs.Weight(i));
  }
  if (!bs.IsRational()) weights.clear();
  return geometry::NurbsCurve(bs.Degree(), std::move(knots), std::move(points), std::move(weights));
}

// `curve`, whose exact B-spline is of degree `degree` > kMaxDegree, approximated by a B-spline of degree
// kMaxDegree within kCadApproximationToleranceMm, as smooth as the curve (up to C2: a rod's frame needs
// its curvature). At most one segment per kMaxDegree of the design's control point limit.
Handle(Geom_BSplineCurve) approximated(const Handle(Geom_Curve)& curve, int degree, const std::filesystem::path& file,
                                       const EdgeRef& ref, CadRodReport& report) {
  constexpr int kMaxSegments = static_cast<int>(geometry::kMaxSplineControls) / geometry::kMaxDegree;
  const GeomAbs_Shape smoothness = curve->Continuity();
  const GeomAbs_Shape order = smoothness >= GeomAbs_C2 ? GeomAbs_C2 : smoothness >= GeomAbs_C1 ? GeomAbs_C1 : GeomAbs_C0;
  const GeomConvert_ApproxCurve approximation(curve, kCadApproximationToleranceMm, order, kMaxSegments, geometry::kMaxDegree);
  if (!approximation.IsDone() || !(approximation.MaxError() <= kCadApproximationToleranceMm)) {
    char tolerance[32], best[32] = "none";
    std::snprintf(tolerance, sizeof tolerance, "%g mm", kCadApproximationToleranceMm);
    if (approximation.HasResult()) std::snprintf(best, sizeof best, "%.3g mm", approximation.MaxError());
    throw MeshError(file, ref.name() + ": a curve of degree " + std::to_string(degree) + ", above the " + std::to_string(geometry::kMaxDegree) +
                              " rodfab supports, that cannot be approximated within " + tolerance +
                              " by " + std::to_string(kMaxSegments) + " pieces of degree " + std::to_string(geometry::kMaxDegree) +
                              " (the closest: " + best + "); split the curve or lower its degree in the CAD program");
  }
  ++report.approximated;
  report.largestApproximationError = std::max(report.largestApproximationError, approximation.MaxError());
  return approximation.Curve();
}

// The edge's curve over its range as a clamped, non-periodic B-spline (approximated when its exact
// one would be of too high a degree); nullopt for an edge without a 3D curve (a degenerate seam).
std::optional<geometry::NurbsCurve> edgeCurve(const std::filesystem::path& file, const EdgeRef& ref, CadRodReport& report) {
  const TopoDS_Edge& edge = TopoDS::Edge(ref.edge);
  if (BRep_Tool::Degenerated(edge)) return std::nullopt;
  double first = 0, last = 0;
  const Handle(Geom_Curve) curve = BRep_Tool::Curve(edge, first, last);
  if (curve.IsNull() || !(last > first)) return std::nullopt;
  try {
    const Handle(Geom_Curve) trimmed = new Geom_TrimmedCurve(curve, first, last);
    Handle(Geom_BSplineCurve) bs = GeomConvert::CurveToBSplineCurve(trimmed);
    if (bs->Degree() > geometry::kMaxDegree) bs = approximated(trimmed, bs->Degree(), file, ref, report);
    if (bs->IsPeriodic()) bs->SetNotPeriodic();
    return toNurbs(*bs, file, ref);
  } catch (const Standard_Failure& e) {
    throw MeshError(file, ref.name() + ": cannot convert its curve to a B-spline: " + e.GetMessageString());
  }
}

// The centerline as the design reader checks it (a zero length from a circle of radius 0, coincident
// points or a unit factor of 0; a length beyond double precision), before a rod and its frame are
// built on it.
void requireValidCenterline(const geometry::NurbsCurve& curve, const std::filesystem::path& file, const EdgeRef& edge) {
  geometry::DesignReader reader;
  reader.centerline(nlohmann::json(geometry::nurbsJson(curve)), "centerline");
  if (!reader.issues.empty()) throw MeshError(file, edge.name() + ": " + reader.issues.front().message);
}

// The curves' ends, 2r the start and 2r + 1 the end of curve r.
std::vector<Vec3> curveEnds(const std::vector<geometry::NurbsCurve>& curves) {
  std::vector<Vec3> ends;
  for (const auto& c : curves) ends.push_back(c.points().front()), ends.push_back(c.points().back());
  return ends;
}

// The ends chained by distances of at most `tolerance` (single linkage), as lists of end numbers in
// increasing order, the lists ordered by their first end; lone ends are left out.
std::vector<std::vector<std::size_t>> chainedEnds(const std::vector<Vec3>& ends, double tolerance) {
  std::vector<std::size_t> order(ends.size()), parent(ends.size());
  std::iota(order.begin(), order.end(), 0);
  std::iota(parent.begin(), parent.end(), 0);
  // Sorted by x, so only ends within the tolerance in x are compared.
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return ends[a].x() < ends[b].x(); });
  auto find = [&](std::size_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (std::size_t i = 0; i < order.size(); ++i)
    for (std::size_t j = i + 1; j < order.size() && ends[order[j]].x() - ends[order[i]].x() <= tolerance; ++j)
      if ((ends[order[i]] - ends[order[j]]).norm() <= tolerance) parent[find(order[i])] = find(order[j]);
  std::vector<std::vector<std::size_t>> members(ends.size());
  for (std::size_t e = 0; e < ends.size(); ++e) members[find(e)].push_back(e);
  std::vector<std::vector<std::size_t>> groups;
  for (auto& m : members)
    if (m.size() > 1) groups.push_back(std::move(m));
  std::sort(groups.begin(), groups.end(), [](const auto& a, const auto& b) { return a.front() < b.front(); });
  return groups;
}

Vec3 meanOf(const std::vector<Vec3>& ends, const std::vector<std::size_t>& group) {
  Vec3 sum = Vec3::Zero();
  for (std::size_t e : group) sum += ends[e];
  return sum / static_cast<double>(group.size());
}

// The two ends of `group` farthest apart (the first such pair in the group's order).
std::pair<std::size_t, std::size_t> farthestPair(const std::vector<Vec3>& ends, const std::vector<std::size_t>& group) {
  std::pair<std::size_t, std::size_t> pair{group[0], group[1]};
  double farthest = -1;
  for (std::size_t i = 0; i < group.size(); ++i) {
    if (i % 1024 == 0) common::throwIfInterrupted();  // a hostile joint of 10^5 ends takes seconds
    for (std::size_t j = i + 1; j < group.size(); ++j)
      if (const double d = (ends[group[i]] - ends[group[j]]).norm(); d > farthest) farthest = d, pair = {group[i], group[j]};
  }
  return pair;
}

// "edge 3 (entity #18 (POLYLINE))'s start at (0, 0, 0)"
std::string endName(const std::vector<Vec3>& ends, const std::vector<EdgeRef>& edgeOfRod, std::size_t end) {
  const Vec3& p = ends[end];
  return edgeOfRod[end / 2].name() + "'s " + (end % 2 == 0 ? "start" : "end") + " at " + formatPoint(gp_Pnt(p.x(), p.y(), p.z()));
}

// `width` (mm) with the fewest significant digits, 3 at least, that still read as more than `limit`:
// a joint 1.0004 mm across at a 1 mm tolerance is not "1 mm across".
std::string widthAbove(double width, double limit) {
  char text[32];
  for (int digits = 3; digits <= 17; ++digits) {
    std::snprintf(text, sizeof text, "%.*g", digits, width);
    if (std::strtod(text, nullptr) > limit) break;
  }
  return text;
}

// A chain of ends, each within the tolerance of the next, can be far wider than the tolerance (a star
// of 10 mm lines whose tips are 1.3 mm apart, at a tolerance of 5 mm, chains into one lump), and moving
// its ends onto one point would move them farther than the tolerance promises: such a chain is
// refused, naming its two ends farthest apart. Ends of a group no wider than the tolerance move by at
// most the tolerance (their mean lies in their convex hull).
void requireCompactJoint(const std::vector<Vec3>& ends, const std::vector<std::size_t>& group, double tolerance,
                         const std::filesystem::path& file, const std::vector<EdgeRef>& edgeOfRod) {
  const Vec3 mean = meanOf(ends, group);
  double fromMean = 0;
  for (std::size_t e : group) fromMean = std::max(fromMean, (ends[e] - mean).norm());
  if (fromMean <= tolerance / 2) return;  // then no two ends are farther apart than the tolerance
  const auto [a, b] = farthestPair(ends, group);
  const double width = (ends[a] - ends[b]).norm();
  if (width <= tolerance) return;
  const std::string across = widthAbove(width, tolerance);
  throw MeshError(file, std::to_string(group.size()) + " curve ends chain into one joint " + across + " mm across, each within the " +
                            "joint tolerance (" + common::exactNumber(tolerance) + " mm) of another: " + endName(ends, edgeOfRod, a) +
                            " and " + endName(ends, edgeOfRod, b) + " are " + across + " mm apart, and one joint would move ends " +
                            "farther than the tolerance; give a --joint-tolerance below the distance between ends that are not " +
                            "to meet (or close the gaps in the model)");
}

// Joins the curve ends within `tolerance` of one another: each group of chained ends (refused when
// wider than the tolerance) is moved onto its mean, so its rods end at exactly one point. Returns how
// far the farthest end moved and counts the joints.
double mergeEnds(std::vector<geometry::NurbsCurve>& curves, double tolerance, std::size_t& joints,
                 const std::filesystem::path& file, const std::vector<EdgeRef>& edgeOfRod) {
  const std::vector<Vec3> ends = curveEnds(curves);
  const std::vector<std::vector<std::size_t>> groups = chainedEnds(ends, tolerance);
  std::vector<Vec3> moved = ends;
  for (const auto& group : groups) {
    requireCompactJoint(ends, group, tolerance, file, edgeOfRod);
    const Vec3 mean = meanOf(ends, group);
    for (std::size_t e : group) moved[e] = mean;
  }
  joints = groups.size();
  double farthest = 0;
  for (std::size_t r = 0; r < curves.size(); ++r) {
    std::vector<Vec3> points = curves[r].points();
    farthest = std::max({farthest, (points.front() - moved[2 * r]).norm(), (points.back() - moved[2 * r + 1]).norm()});
    points.front() = moved[2 * r], points.back() = moved[2 * r + 1];
    curves[r] = geometry::NurbsCurve(curves[r].degree(), curves[r].knots(), std::move(points), curves[r].weights());
  }
  return farthest;
}

// A reference normal perpendicular to the curve's start tangent (for non-circular sections).
Vec3 normalFor(const geometry::NurbsCurve& c) {
  Vec3 d[3];
  c.derivatives(c.domainBegin(), 2, d);
  const Vec3 t = d[1].norm() > 0 ? d[1].normalized() : d[2].normalized();
  int k = 0;
  t.cwiseAbs().minCoeff(&k);
  return t.cross(Vec3::Unit(k)).normalized();
}

// Builds every rod once, as the design reader will, and lets it go: a centerline too intricate to
// sample is named by its edge here, where the edge is known. Both cores, a rod a thread at a time (a
// winding one takes ~1 MB); the first failing rod in the model's order is reported whatever the
// thread count.
void requireRodsBuild(const std::vector<geometry::NurbsCurve>& curves, const std::vector<std::optional<Vec3>>& normals,
                      const CadRodOptions& options, const std::filesystem::path& file, const std::vector<EdgeRef>& edgeOfRod) {
  std::vector<std::string> failures(curves.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, curves.size(), 1), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t r = range.begin(); r != range.end(); ++r) {
      const geometry::NurbsCurve& c = curves[r];
      try {
        const geometry::Rod rod("edge-" + std::to_string(r), c, options.section, normals[r], std::nullopt, options.caps,
                                geometry::BSplineField::constant(options.modulusMpa, c.domainBegin(), c.domainEnd()));
      } catch (const std::invalid_argument& e) {  // e.g. a centerline too intricate to sample
        failures[r] = e.what();
      }
    }
  });
  for (std::size_t r = 0; r < curves.size(); ++r)
    if (!failures[r].empty()) throw MeshError(file, edgeOfRod[r].name() + ": " + failures[r]);
}

}  // namespace

namespace detail {

CadDesign readCadDesign(const std::filesystem::path& file, const CadRodOptions& options) {
  // The options and checkCadFile (format, size, memory) were checked by rodsFromCad, which runs this.
  std::lock_guard<std::mutex> lock(readerMutex());
  Message::DefaultMessenger()->RemovePrinters(STANDARD_TYPE(Message_Printer));
  STEPControl_Reader stepReader;
  IGESControl_Reader igesReader;
  XSControl_Reader& reader = isStep(file) ? static_cast<XSControl_Reader&>(stepReader) : static_cast<XSControl_Reader&>(igesReader);
  const TopoDS_Shape shape = readShape(reader, file);
  TopTools_IndexedMapOfShape edges;
  if (!shape.IsNull()) TopExp::MapShapes(shape, TopAbs_EDGE, edges);
  CadDesign out;
  out.report.edges = static_cast<std::size_t>(edges.Extent());
  std::vector<geometry::NurbsCurve> curves;
  std::vector<EdgeRef> edgeOfRod;
  for (int i = 1; i <= edges.Extent(); ++i) {
    common::throwIfInterrupted();
    const EdgeRef ref{reader, edges(i), i - 1};
    if (auto c = edgeCurve(file, ref, out.report)) curves.push_back(std::move(*c)), edgeOfRod.push_back(ref);
    else ++out.report.skippedDegenerate;
  }
  const TransferFailures failures = transferFailures(reader);
  out.report.untranslated = failures.entities, out.report.firstUntranslated = failures.first;
  if (curves.empty())
    throw MeshError(file, "the model holds no edge curve" +
                              (failures.entities ? "; OpenCASCADE could not convert " + failures.first +
                                                       (failures.entities > 1 ? " (and " + std::to_string(failures.entities - 1) + " more entities)" : "")
                                                 : std::string()));
  out.report.largestEndMove = mergeEnds(curves, options.jointTolerance, out.report.joints, file, edgeOfRod);
  std::vector<std::optional<Vec3>> normals(curves.size());
  for (std::size_t r = 0; r < curves.size(); ++r) {
    // After mergeEnds: an edge shorter than the joint tolerance has both ends on one point now.
    requireValidCenterline(curves[r], file, edgeOfRod[r]);
    if (!options.section.isRotationallySymmetric()) normals[r] = normalFor(curves[r]);
  }
  requireRodsBuild(curves, normals, options, file, edgeOfRod);
  for (const geometry::NurbsCurve& c : curves) {
    const double radius = smallestBendRadius(c);
    out.report.smallestBendRadius = std::min(out.report.smallestBendRadius, radius);
    out.report.rodsBentTighterThanSection += radius < options.section.boundingRadius();
  }
  nlohmann::ordered_json rods = nlohmann::ordered_json::array();
  for (std::size_t r = 0; r < curves.size(); ++r) {
    const geometry::NurbsCurve& c = curves[r];
    rods.push_back(geometry::rodJson("edge-" + std::to_string(r), c, options.section, normals[r], std::nullopt, options.caps,
                                     geometry::BSplineField::constant(options.modulusMpa, c.domainBegin(), c.domainEnd())));
  }
  out.design = geometry::designJson(std::move(rods));
  out.report.rods = curves.size();
  return out;
}

}  // namespace detail

}  // namespace rodfab::meshing
