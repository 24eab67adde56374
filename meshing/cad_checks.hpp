// Internal to the CAD reader process (cad_reader.hpp): the checks that keep a hostile STEP or IGES
// file from crashing or hanging OpenCASCADE. Its reader and its transfer trust the entity graph they
// are given (a null handle in a point list, a degree of a million, a curve set containing itself: each
// a SIGSEGV), so rodfab checks the text before the reader sees it and the loaded model before the
// transfer follows it, and names what it finds; a crash these checks miss still ends in the reader
// process (rodsFromCad reports it). Each check throws MeshError naming the file and, where there is
// one, the line or the entity.
#pragma once

#include "meshing/meshing.hpp"

#include <Standard_Handle.hxx>

#include <filesystem>
#include <string>

class Interface_InterfaceModel;
class gp_Pnt;
class Standard_Transient;
class XSControl_Reader;

namespace rodfab::meshing::detail {

// The deepest list nesting accepted in a STEP file. Real models need a handful of levels (a B-spline
// surface's weights are a list of lists inside an entity's parameters); OpenCASCADE's parser recurses
// per level, so 100,000 levels overflow its stack.
inline constexpr int kMaxStepNesting = 64;
// The largest STEP entity id accepted: OpenCASCADE reads ids into 32-bit integers without checking.
inline constexpr long long kMaxStepEntityId = 999'999'999;

// OpenCASCADE's STEP parser appends each element of a list by walking the list from its start, so a
// list of n elements costs n * n / 2 steps: 200,000 elements took 27 s. Accepted: lists below
// kMaxStepListLength elements whose lengths squared sum to at most kMaxStepListSquares (about 7 s of
// that walking on this project's machine; real models have many short lists and few long ones).
inline constexpr long long kMaxStepListLength = 100'000;
inline constexpr double kMaxStepListSquares = 1e10;

// What OpenCASCADE's STEP parser cannot take, found by one pass over the text: lists nested deeper than
// kMaxStepNesting, lists too long (above), and entity ids (#N) above kMaxStepEntityId, named by line.
void prescanStepText(const std::filesystem::path& file);
// What OpenCASCADE's IGES parser cannot take (iges_text_checks.cpp), named by line: B-spline curves and
// surfaces (types 126 and 128) whose degree or pole count is out of range or whose record holds fewer
// values than those counts need; B-rep records (solid, shell, face, loop, edge and vertex lists) whose
// item count is not a whole number or runs past the record; directory or parameter records whose
// sequence number is not a number; a file without its Terminate record (cut short).
void prescanIgesText(const std::filesystem::path& file);

// The loaded model, before any transfer: no failure recorded while loading (unresolved references,
// parameters of the wrong type or count), no entity that refers to itself through others, B-spline
// degrees and pole counts OpenCASCADE's geometry accepts, and vertices at 3D points.
void checkLoadedModel(const XSControl_Reader& reader, const std::filesystem::path& file);

// The entities of the model that no rod comes from, after TransferRoots: those whose transfer failed
// (its check list's failures: an entity that fails is left out of the shape with all it holds, a curve
// set with one unconvertible curve losing every curve in it), the curves of STEP curve sets that were
// left out of their set's shape (OpenCASCADE only warns of those), and IGES composite curves whose
// members were left out while loading (a pointer to no entity). Each entity counted once, the first
// in the model's order named.
struct TransferFailures {
  std::size_t entities = 0;  // entities left out
  std::string first;         // "entity #15 (GEOMETRIC_CURVE_SET): Exception is raised. Entity was not translated."
};
TransferFailures transferFailures(const XSControl_Reader& reader);

// A point as messages show it: "(-1e+20, 20, 30)".
std::string formatPoint(const gp_Pnt& p);

// An entity as messages name it: "#17 (BSplineCurveWithKnots)" in STEP, "D5 (BSplineCurve)" in IGES.
std::string entityName(const Handle(Interface_InterfaceModel)& model, const Handle(Standard_Transient)& entity);

}  // namespace rodfab::meshing::detail
