// What a design file says beyond its rods: the optional "mechanics" block (material constants,
// joints, supports, loads, training load cases with their targets) for the Cosserat rod solver, and
// the optional "optimize" block for `rodfab optimize`. Plain data, read and written by
// mechanics/mechanics_file.hpp, interpreted by the solver (mechanics.hpp) and the optimizer (optimize/).
#pragma once

#include "geometry/frame.hpp"
#include "geometry/nurbs.hpp"
#include "geometry/rod.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::mechanics {

// Most load steps a design or the command line may ask for. Steps are the continuation of a
// nonlinear solve (10 by default; buckling designs use tens), each a converged Newton solve, so a
// bound keeps a typo (100000) from being hours of work: 1,000 steps of one rod take about a second.
inline constexpr int kMaxLoadSteps = 1000;

enum class RodEnd { Start, End };

// A place on the structure that joints, loads and supports act on: one end of a named rod
// ({"rod", "end"}), a point of a named rod by its centerline parameter ({"rod", "parameter"}), or
// what lies at a point ({"point"}): the rod end (or joint) within the joint tolerance, else the
// nearest point of a rod's interior within it. Joints act on interior points too (T-joints).
struct RodEndRef {
  std::string rod;  // empty when given by `point`
  RodEnd end = RodEnd::Start;             // with `rod` and no `parameter`
  std::optional<double> parameter;        // with `rod`: u in the rod's centerline domain
  std::optional<Eigen::Vector3d> point;   // mm
  std::string path;  // JSON path, for messages about this reference
};

enum class SupportKind {
  Clamped,  // position and orientation prescribed
  Pinned,   // position prescribed, rotation free
};

struct Support {
  RodEndRef at;
  SupportKind kind = SupportKind::Clamped;
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();  // mm, reached at the last load step
  Eigen::Vector3d rotation = Eigen::Vector3d::Zero();      // rad, axis * angle in space; clamped only
};

// Force and moment at a rod end, joint or interior point, scaled by the load factor. Given in space
// for the drawn shape; a dead load keeps that direction, a follower load ("follower": true) keeps
// its direction in the cross-section's material frame there: in the deformed state it is
// R R0^T times the given vector, R0 and R the section's rotation drawn and deformed (at a joint
// every rod's section turns alike, the joint being rigid).
struct PointLoad {
  RodEndRef at;
  Eigen::Vector3d force = Eigen::Vector3d::Zero();   // N
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();  // N mm
  bool follower = false;
};

// Dead force per unit of reference length along a whole rod (for example its weight).
struct DistributedLoad {
  std::string rod;
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  // N / mm
  std::string path;
};

// Per-rod overrides of the section's derived constants.
struct RodMechanics {
  std::string rod;
  std::optional<double> torsionConstant;  // mm^4, replaces the section's Saint-Venant J
  std::optional<double> shearFactor;
  std::optional<double> poissonRatio;
};

struct LoadCase;

struct MechanicsSpec {
  bool present = false;  // the design has a "mechanics" block
  double poissonRatio = 0.45;               // PolyJet photopolymers are nearly incompressible
  std::optional<double> shearFactor;        // default: Cowper's factor of each section shape
  // mm: rod ends closer than this are joined rigidly, and so is a rod end this close to another
  // rod's interior (a T-joint)
  double jointTolerance = 1e-3;
  bool inferJoints = true;                  // "joints": "auto" (default) or an explicit list
  std::vector<std::vector<RodEndRef>> joints;
  std::vector<Support> supports;
  std::vector<PointLoad> loads;
  std::vector<DistributedLoad> distributedLoads;
  std::vector<RodMechanics> rods;
  int loadSteps = 10;
  // "load_cases": training cases for design optimization; empty when the design gives its supports
  // and loads at the top of the block (then they are the one case).
  std::vector<LoadCase> loadCases;
};

// ---- Design optimization (`rodfab optimize`) -------------------------------------------------

// The shape one rod should take in a load case: its centerline, and the frames that give the
// target curvature (the orientation spline, else the rotation-minimizing frame seeded with the
// reference normal, else with the design rod's own frame at its start). The target's parameter
// is mapped linearly onto the design rod's.
struct TargetRod {
  std::string rod;  // the design rod's name
  geometry::NurbsCurve centerline;
  std::optional<geometry::QuaternionSpline> orientation;
  std::optional<geometry::Vec3> referenceNormal;
  std::string path;  // JSON path (or file and path) for messages
};

// One training case: the supports and loads (as at the top of the mechanics block) and the shape
// they should produce. A rod without a target does not count in the objective.
struct LoadCase {
  std::string name;
  std::vector<Support> supports;
  std::vector<PointLoad> loads;
  std::vector<DistributedLoad> distributedLoads;
  int loadSteps = 10;
  std::vector<TargetRod> target;
  std::string targetDesign;  // "target": {"design": PATH} as written, empty for inline rods
  double weight = 1.0;
  std::string path;  // "mechanics.load_cases[i]"
};

// The optional top-level "optimize" block: settings of `rodfab optimize`.
struct OptimizeSpec {
  bool present = false;
  double positionWeight = 1.0;   // C_r
  double curvatureWeight = 1.0;  // C_k
  int modulusControls = 4;       // control values of E(u) per rod
  int modulusDegree = 3;         // (clamped to modulusControls - 1)
  std::optional<std::pair<double, double>> boundsMpa;  // default: the calibration's range
  int maxIterations = 200;
  double tolerance = 1e-7;       // on the projected gradient of g / g0
};

// A design as its file gives it: the rods (geometry's RodStructure, so a Design goes wherever rods
// are expected) with the mechanics and optimize blocks.
struct Design : geometry::RodStructure {
  Design() = default;
  // The rods with neither block.
  explicit Design(geometry::RodStructure rods) : geometry::RodStructure(std::move(rods)) {}

  MechanicsSpec mechanics;  // loads and supports for `rodfab simulate`; ignored by the slicer
  OptimizeSpec optimize{};  // the "optimize" block for `rodfab optimize`; ignored by the slicer
};

}  // namespace rodfab::mechanics
