// The CAD reader's input checks (cad_checks.hpp): the STEP text before OpenCASCADE parses it, the loaded
// entity graph before OpenCASCADE transfers it. The IGES text checks are in iges_text_checks.cpp.
#include "meshing/cad_checks.hpp"

#include "common/interrupt.hpp"
#include "common/quoted_text.hpp"

#include <Geom_BSplineCurve.hxx>
#include <Geom_BSplineSurface.hxx>
#include <IGESGeom_BSplineCurve.hxx>
#include <IGESGeom_CompositeCurve.hxx>
#include <IGESGeom_Line.hxx>
#include <IGESToBRep.hxx>
#include <IGESGeom_BSplineSurface.hxx>
#include <IGESSolid_EdgeList.hxx>
#include <IGESSolid_Loop.hxx>
#include <IGESSolid_VertexList.hxx>
#include <Interface_Check.hxx>
#include <Interface_CheckIterator.hxx>
#include <Interface_EntityIterator.hxx>
#include <Interface_Graph.hxx>
#include <Interface_InterfaceModel.hxx>
#include <StepGeom_BSplineCurve.hxx>
#include <StepGeom_BSplineCurveWithKnots.hxx>
#include <StepGeom_BSplineCurveWithKnotsAndRationalBSplineCurve.hxx>
#include <StepGeom_BSplineSurface.hxx>
#include <StepGeom_BSplineSurfaceWithKnots.hxx>
#include <StepGeom_BSplineSurfaceWithKnotsAndRationalBSplineSurface.hxx>
#include <StepGeom_CartesianPoint.hxx>
#include <StepGeom_HArray1OfCartesianPoint.hxx>
#include <StepGeom_HArray2OfCartesianPoint.hxx>
#include <StepGeom_RationalBSplineCurve.hxx>
#include <StepGeom_RationalBSplineSurface.hxx>
#include <StepGeom_Curve.hxx>
#include <StepShape_GeometricSet.hxx>
#include <StepShape_GeometricSetSelect.hxx>
#include <StepShape_VertexPoint.hxx>
#include <TCollection_HAsciiString.hxx>
#include <TransferBRep.hxx>
#include <Transfer_TransientProcess.hxx>
#include <XSControl_Reader.hxx>
#include <XSControl_TransferReader.hxx>
#include <XSControl_WorkSession.hxx>
#include <gp_Pnt.hxx>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace rodfab::meshing::detail {

namespace {

std::string checkText(const Handle(Interface_Check)& check) {
  std::string text;
  for (int i = 1; i <= check->NbFails() && i <= 3; ++i) text += (i > 1 ? "; " : "") + std::string(check->CFail(i));
  if (check->NbFails() > 3) text += "; and " + std::to_string(check->NbFails() - 3) + " more";
  return common::printableFromFile(text, 600);  // OpenCASCADE's messages quote the file's own words
}

// Every failure OpenCASCADE recorded while loading the file (its syntactic check list): references to
// absent entities, parameters of the wrong type or count. The transfer would dereference what they left null.
void refuseLoadFailures(const XSControl_Reader& reader, const std::filesystem::path& file) {
  const Handle(Interface_InterfaceModel) model = reader.Model();
  const Interface_CheckIterator checks = reader.WS()->ModelCheckList(Standard_False);
  int failed = 0;
  std::string first;
  for (checks.Start(); checks.More(); checks.Next()) {
    const Handle(Interface_Check)& check = checks.Value();
    if (check.IsNull() || !check->HasFailed()) continue;
    if (failed++ == 0) {
      const int n = checks.Number();
      const std::string where = n > 0 && n <= model->NbEntities() ? "entity " + entityName(model, model->Value(n)) : "the file";
      first = where + ": " + checkText(check);
    }
  }
  if (failed > 0)
    throw MeshError(file, "malformed: " + first +
                              (failed > 1 ? " (and " + std::to_string(failed - 1) + " more entities with errors)" : ""));
}

// Entities that refer to themselves, directly or through others: OpenCASCADE's transfer follows
// references recursively and never returns. Depth-first search with an explicit stack (a hostile
// chain of references is as deep as the file is long).
void refuseReferenceCycles(const XSControl_Reader& reader, const std::filesystem::path& file) {
  const Handle(Interface_InterfaceModel) model = reader.Model();
  const Interface_Graph& graph = reader.WS()->Graph();
  const int n = model->NbEntities();
  enum : char { kNew, kOpen, kDone };
  std::vector<char> state(std::size_t(n) + 1, kNew);
  std::vector<std::pair<int, Interface_EntityIterator>> stack;
  for (int root = 1; root <= n; ++root) {
    if (state[root] != kNew) continue;
    common::throwIfInterrupted();
    state[root] = kOpen;
    stack.emplace_back(root, graph.Shareds(model->Value(root)));
    while (!stack.empty()) {
      Interface_EntityIterator& next = stack.back().second;
      if (!next.More()) {
        state[stack.back().first] = kDone;
        stack.pop_back();
        continue;
      }
      const int m = model->Number(next.Value());
      next.Next();
      if (m <= 0 || state[m] == kDone) continue;
      if (state[m] == kOpen)
        throw MeshError(file, "malformed: entity " + entityName(model, model->Value(m)) +
                                  " refers to itself (directly or through other entities)");
      state[m] = kOpen;
      stack.emplace_back(m, graph.Shareds(model->Value(m)));
    }
  }
}

// What Geom_BSplineCurve/Surface accept (1 <= degree <= MaxDegree(), at least degree + 1 poles):
// OpenCASCADE's converters index arrays by these numbers before its constructors check them.
std::string splineProblem(int degree, int poles, int maxDegree) {
  if (degree < 1 || degree > maxDegree)
    return "degree " + std::to_string(degree) + ", expected 1 to " + std::to_string(maxDegree);
  if (poles < degree + 1)
    return std::to_string(poles) + " control points, expected at least degree + 1 = " + std::to_string(degree + 1);
  return {};
}

// A STEP knot list and its multiplicities: both present and not empty (the converter reads the first
// of each unchecked; an empty one written in the file already crashes the loader, so the text scan
// refuses it) and as long as each other (the transfer dropped such a curve without a word). Other
// inconsistencies OpenCASCADE's constructors refuse themselves.
std::string knotsProblem(const Handle(TColStd_HArray1OfReal)& knots, const Handle(TColStd_HArray1OfInteger)& multiplicities) {
  if (knots.IsNull() || multiplicities.IsNull() || knots->Length() == 0 || multiplicities->Length() == 0) return "no knots";
  if (knots->Length() != multiplicities->Length())
    return std::to_string(knots->Length()) + " knots but " + std::to_string(multiplicities->Length()) + " multiplicities";
  return {};
}

std::string stepCurveProblem(const Handle(StepGeom_BSplineCurve)& c) {
  const Handle(StepGeom_HArray1OfCartesianPoint) points = c->ControlPointsList();
  if (points.IsNull()) return "no control points";
  for (int i = points->Lower(); i <= points->Upper(); ++i)
    if (points->Value(i).IsNull()) return "control point " + std::to_string(i) + " missing";
  if (auto k = Handle(StepGeom_BSplineCurveWithKnots)::DownCast(c); !k.IsNull())
    if (std::string problem = knotsProblem(k->Knots(), k->KnotMultiplicities()); !problem.empty()) return problem;
  if (auto r = Handle(StepGeom_BSplineCurveWithKnotsAndRationalBSplineCurve)::DownCast(c);
      !r.IsNull() && (r->BSplineCurveWithKnots().IsNull() || r->RationalBSplineCurve().IsNull()))
    return "an incomplete rational B-spline";
  return splineProblem(c->Degree(), points->Length(), Geom_BSplineCurve::MaxDegree());
}

std::string stepSurfaceProblem(const Handle(StepGeom_BSplineSurface)& s) {
  const Handle(StepGeom_HArray2OfCartesianPoint) points = s->ControlPointsList();
  if (points.IsNull()) return "no control points";
  for (int i = points->LowerRow(); i <= points->UpperRow(); ++i)
    for (int j = points->LowerCol(); j <= points->UpperCol(); ++j)
      if (points->Value(i, j).IsNull()) return "control point (" + std::to_string(i) + ", " + std::to_string(j) + ") missing";
  if (auto k = Handle(StepGeom_BSplineSurfaceWithKnots)::DownCast(s); !k.IsNull()) {
    if (std::string problem = knotsProblem(k->UKnots(), k->UMultiplicities()); !problem.empty()) return "in u: " + problem;
    if (std::string problem = knotsProblem(k->VKnots(), k->VMultiplicities()); !problem.empty()) return "in v: " + problem;
  }
  if (auto r = Handle(StepGeom_BSplineSurfaceWithKnotsAndRationalBSplineSurface)::DownCast(s);
      !r.IsNull() && (r->BSplineSurfaceWithKnots().IsNull() || r->RationalBSplineSurface().IsNull()))
    return "an incomplete rational B-spline";
  const int maxDegree = Geom_BSplineSurface::MaxDegree();
  std::string u = splineProblem(s->UDegree(), points->ColLength(), maxDegree);
  return u.empty() ? splineProblem(s->VDegree(), points->RowLength(), maxDegree) : "in u: " + u;
}

// IGES keeps only the upper pole index N (poles 0..N), so the counts are checked before any array.
std::string igesProblem(const Handle(Standard_Transient)& entity) {
  if (auto c = Handle(IGESGeom_BSplineCurve)::DownCast(entity); !c.IsNull())
    return splineProblem(c->Degree(), c->UpperIndex() + 1, Geom_BSplineCurve::MaxDegree());
  if (auto s = Handle(IGESGeom_BSplineSurface)::DownCast(entity); !s.IsNull()) {
    const int maxDegree = Geom_BSplineSurface::MaxDegree();
    std::string u = splineProblem(s->DegreeU(), s->UpperIndexU() + 1, maxDegree);
    return u.empty() ? splineProblem(s->DegreeV(), s->UpperIndexV() + 1, maxDegree) : "in u: " + u;
  }
  return {};
}

std::string splineEntityProblem(const Handle(Standard_Transient)& entity) {
  if (auto c = Handle(StepGeom_BSplineCurve)::DownCast(entity); !c.IsNull()) return stepCurveProblem(c);
  if (auto s = Handle(StepGeom_BSplineSurface)::DownCast(entity); !s.IsNull()) return stepSurfaceProblem(s);
  return igesProblem(entity);
}

void refuseBadSplines(const XSControl_Reader& reader, const std::filesystem::path& file) {
  const Handle(Interface_InterfaceModel) model = reader.Model();
  for (int i = 1; i <= model->NbEntities(); ++i)
    if (const std::string problem = splineEntityProblem(model->Value(i)); !problem.empty())
      throw MeshError(file, "malformed: B-spline entity " + entityName(model, model->Value(i)) + ": " + problem);
}

// IGES topology refers into lists by index: a loop's edges into edge lists (or vertex lists), an edge
// list's ends into vertex lists. OpenCASCADE's transfer reads the indices unchecked: an index past its
// list was a SIGSEGV (scripts/mutate_cad.py, a loop of make_test_cad's box in IGES); so was an edge
// on a line of zero length.
std::string listIndexProblem(const Handle(Standard_Transient)& list, int index) {
  int count = -1;
  if (auto edges = Handle(IGESSolid_EdgeList)::DownCast(list); !edges.IsNull()) count = edges->NbEdges();
  else if (auto vertices = Handle(IGESSolid_VertexList)::DownCast(list); !vertices.IsNull()) count = vertices->NbVertices();
  else return list.IsNull() ? "a missing list" : "";
  if (index >= 1 && index <= count) return {};
  return "item " + std::to_string(index) + " of a list of " + std::to_string(count);
}

// OpenCASCADE takes a coordinate of 1e100 or more as infinite (Precision::Infinite() is 2e100): a
// line ending there leaves its edge null, which the loop's transfer dereferenced (a SIGSEGV,
// scripts/mutate_cad.py). A design holds coordinates within +-1e9 mm, at most ~4e13 of IGES's smallest
// unit (the microinch), so nothing beyond 1e15 in the file's unit can become one.
constexpr double kMaxIgesCoordinate = 1e15;

std::string igesTopologyProblem(const Handle(Standard_Transient)& entity) {
  if (auto loop = Handle(IGESSolid_Loop)::DownCast(entity); !loop.IsNull()) {
    for (int i = 1; i <= loop->NbEdges(); ++i) {
      // Its type says what its list is: 0 an edge list, 1 a vertex list (IGES 5.3, entity 508). Any
      // other type, or a list of the other kind, was a SIGSEGV in the transfer (scripts/mutate_cad.py).
      const int type = loop->EdgeType(i);
      const bool edgeList = !Handle(IGESSolid_EdgeList)::DownCast(loop->Edge(i)).IsNull();
      const bool vertexList = !Handle(IGESSolid_VertexList)::DownCast(loop->Edge(i)).IsNull();
      if (!(type == 0 && edgeList) && !(type == 1 && vertexList))
        return "edge " + std::to_string(i) + " is of type " + std::to_string(type) + " on " +
               (edgeList ? "an edge list" : vertexList ? "a vertex list" : "no list") +
               " (expected type 0 on an edge list or 1 on a vertex list)";
      if (std::string problem = listIndexProblem(loop->Edge(i), loop->ListIndex(i)); !problem.empty())
        return "edge " + std::to_string(i) + " refers to " + problem;
      // Its curves in the face's parameter space: a count running into the next edge's values made
      // them an edge list and a null pointer (a SIGSEGV in the transfer, scripts/mutate_cad.py).
      for (int j = 1; j <= loop->NbParameterCurves(i); ++j) {
        const Handle(IGESData_IGESEntity) curve = loop->ParametricCurve(i, j);
        if (curve.IsNull() || !(IGESToBRep::IsBasicCurve(curve) || IGESToBRep::IsTopoCurve(curve)))
          return "edge " + std::to_string(i) + "'s parameter-space curve " + std::to_string(j) + " is " +
                 (curve.IsNull() ? std::string("missing") : "an entity of type " + std::to_string(curve->TypeNumber()) + ", not a curve");
      }
    }
  } else if (auto edges = Handle(IGESSolid_EdgeList)::DownCast(entity); !edges.IsNull()) {
    for (int i = 1; i <= edges->NbEdges(); ++i) {
      std::string problem = listIndexProblem(edges->StartVertexList(i), edges->StartVertexIndex(i));
      if (problem.empty()) problem = listIndexProblem(edges->EndVertexList(i), edges->EndVertexIndex(i));
      if (!problem.empty()) return "edge " + std::to_string(i) + "'s vertex is " + problem;
      // A line of zero length as an edge: its wire comes back null and the loop's transfer dereferences
      // it (a SIGSEGV in ShapeExtend_WireData::NbEdges; scripts/mutate_cad.py, make_test_cad's box).
      const Handle(IGESGeom_Line) line = Handle(IGESGeom_Line)::DownCast(edges->Curve(i));
      if (!line.IsNull() && line->StartPoint().Distance(line->EndPoint()) == 0.0)
        return "edge " + std::to_string(i) + "'s curve is a line of zero length (it starts and ends at the same point)";
    }
  } else if (auto line = Handle(IGESGeom_Line)::DownCast(entity); !line.IsNull()) {
    for (const gp_Pnt& end : {line->StartPoint(), line->EndPoint()})
      if (!(std::max({std::abs(end.X()), std::abs(end.Y()), std::abs(end.Z())}) <= kMaxIgesCoordinate))
        return "a line ending at " + formatPoint(end) + ", beyond +-1e15 in the file's unit (no design holds it: a wrong unit or a corrupt file?)";
  }
  return {};
}

void refuseBadIgesTopology(const XSControl_Reader& reader, const std::filesystem::path& file) {
  const Handle(Interface_InterfaceModel) model = reader.Model();
  for (int i = 1; i <= model->NbEntities(); ++i)
    if (const std::string problem = igesTopologyProblem(model->Value(i)); !problem.empty())
      throw MeshError(file, "malformed: entity " + entityName(model, model->Value(i)) + ": " + problem);
}

// A vertex at a point that is not 3D (a 2D point, or an empty coordinate list, which OpenCASCADE reads
// as 2D): a SIGSEGV in the transfer, found by scripts/mutate_cad.py. The reader process contains such
// crashes; this says what is wrong. (An empty DIRECTION crashes OpenCASCADE's own load check, before
// any check of ours can run: the reader process reports that one.)
std::string pointProblem(const Handle(Standard_Transient)& entity) {
  const Handle(StepShape_VertexPoint) vertex = Handle(StepShape_VertexPoint)::DownCast(entity);
  if (vertex.IsNull()) return {};
  const Handle(StepGeom_CartesianPoint) p = Handle(StepGeom_CartesianPoint)::DownCast(vertex->VertexGeometry());
  if (p.IsNull() || p->NbCoordinates() == 3) return {};
  return "a vertex whose point is not 3D (" + std::to_string(p->NbCoordinates()) + " coordinates read, expected 3)";
}

void refuseBadPoints(const XSControl_Reader& reader, const std::filesystem::path& file) {
  const Handle(Interface_InterfaceModel) model = reader.Model();
  for (int i = 1; i <= model->NbEntities(); ++i)
    if (const std::string problem = pointProblem(model->Value(i)); !problem.empty())
      throw MeshError(file, "malformed: entity " + entityName(model, model->Value(i)) + ": " + problem);
}

// A curve of a STEP curve set that the transfer made no edge of: OpenCASCADE converts a set's members
// one by one and leaves out those it cannot convert (a circle of negative radius, a B-spline weight of
// 0, a line of zero direction, trim values written as integers) with a warning, not a failure, so its check
// list does not hold them. A set that failed as a whole is in that list already, with its members.
void addDroppedSetMembers(const Handle(Transfer_TransientProcess)& process, const Handle(Interface_InterfaceModel)& model,
                          int number, std::map<int, std::string>& lost) {
  const Handle(StepShape_GeometricSet) set = Handle(StepShape_GeometricSet)::DownCast(model->Value(number));
  if (set.IsNull() || TransferBRep::ShapeResult(process, set).IsNull()) return;
  for (int i = 1; i <= set->NbElements(); ++i) {
    const Handle(Standard_Transient) member = set->ElementsValue(i).Value();
    if (member.IsNull() || !member->IsKind(STANDARD_TYPE(StepGeom_Curve)) || !TransferBRep::ShapeResult(process, member).IsNull()) continue;
    lost.emplace(model->Number(member), "entity " + entityName(model, member) + ", curve " + std::to_string(i) + " of " +
                                            entityName(model, set) + ": OpenCASCADE made no edge of it (not a valid curve)");
  }
}

// An IGES composite curve whose member list OpenCASCADE's reader shortened while loading it (a pointer to
// a directory entry the file does not hold, or not a curve: left out with a warning, so the transfer
// joins the members that remain and nothing fails).
void addDroppedCompositeMembers(const Handle(Interface_InterfaceModel)& model, int number, std::map<int, std::string>& lost) {
  if (Handle(IGESGeom_CompositeCurve)::DownCast(model->Value(number)).IsNull()) return;
  const Handle(Interface_Check)& check = model->Check(number, Standard_True);
  if (check.IsNull()) return;
  // Only the member list's warning ("Some pointers in entity list are null or negative"): a bad
  // associativity or property pointer is warned about too, and loses no member.
  std::string text;
  for (int i = 1; i <= check->NbWarnings(); ++i)
    if (const std::string w = check->CWarning(i); w.find("entity list") != std::string::npos) text += (text.empty() ? "" : "; ") + w;
  if (text.empty()) return;
  lost.emplace(number, "entity " + entityName(model, model->Value(number)) + ": members left out while reading it: " +
                           common::printableFromFile(text, 600));
}

}  // namespace

TransferFailures transferFailures(const XSControl_Reader& reader) {
  TransferFailures out;
  const Handle(XSControl_TransferReader) transfer = reader.WS()->TransferReader();
  if (transfer.IsNull() || transfer->TransientProcess().IsNull()) return out;
  const Handle(Transfer_TransientProcess) process = transfer->TransientProcess();
  const Handle(Interface_InterfaceModel) model = reader.Model();
  std::map<int, std::string> lost;  // by entity number: the model's order, each entity once
  const Interface_CheckIterator checks = process->CheckList(Standard_True);
  for (checks.Start(); checks.More(); checks.Next()) {
    const Handle(Interface_Check)& check = checks.Value();
    if (check.IsNull() || !check->HasFailed()) continue;
    // A failure of no entity (the model's own) is kept too, numbered below every entity.
    const int number = check->HasEntity() ? model->Number(check->Entity()) : -static_cast<int>(lost.size()) - 1;
    lost.emplace(number, (number > 0 ? "entity " + entityName(model, check->Entity()) : std::string("the model")) + ": " + checkText(check));
  }
  for (int i = 1; i <= model->NbEntities(); ++i) {
    addDroppedSetMembers(process, model, i, lost);
    addDroppedCompositeMembers(model, i, lost);
  }
  out.entities = lost.size();
  if (!lost.empty()) out.first = lost.begin()->second;
  return out;
}

void checkLoadedModel(const XSControl_Reader& reader, const std::filesystem::path& file) {
  refuseLoadFailures(reader, file);
  refuseBadSplines(reader, file);
  refuseBadPoints(reader, file);
  refuseBadIgesTopology(reader, file);
  refuseReferenceCycles(reader, file);
}

std::string formatPoint(const gp_Pnt& p) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.6g, %.6g, %.6g)", p.X(), p.Y(), p.Z());
  return text;
}

std::string entityName(const Handle(Interface_InterfaceModel)& model, const Handle(Standard_Transient)& entity) {
  const Handle(TCollection_HAsciiString) label = model->StringLabel(entity);
  std::string name;
  if (!label.IsNull() && label->Length() > 0 && !std::isdigit(static_cast<unsigned char>(label->Value(1)))) name = label->ToCString();
  else name.append("#").append(std::to_string(model->Number(entity)));
  // IGES type names come padded ("126 0   BSplineCurve   "): one space between words.
  name.append(" (");
  char previous = '(';
  for (const char* c = model->TypeName(entity, Standard_False); *c; previous = *c++)
    if (*c != ' ') {
      if (previous == ' ' && name.back() != '(') name.push_back(' ');
      name.push_back(*c);
    }
  // A label or an unknown STEP type comes from the file as written.
  return common::printableFromFile(name.append(")"), 200);
}

}  // namespace rodfab::meshing::detail
