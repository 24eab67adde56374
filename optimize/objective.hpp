// The shape objective of one load case: targets sampled at the collocation points, and the two
// terms of g with their gradient with respect to the state. Internal to optimize/.
#pragma once

#include "geometry/rod.hpp"
#include "mechanics/mechanics.hpp"

#include <Eigen/Core>

#include <vector>

namespace rodfab::optimize::detail {

// One rod's target at its collocation points: positions (mm) and material curvatures (1/mm).
struct RodTarget {
  std::size_t rod = 0;
  double length = 0.0;
  std::vector<Eigen::Vector3d> position, curvature;
};

// Samples `targets` (matched to the design's rods by name) at the collocation points of `problem`.
// Throws OptimizeError for a target rod missing from the design or named twice.
std::vector<RodTarget> sampleTargets(const mechanics::Design& design, const std::vector<mechanics::TargetRod>& targets,
                                     const mechanics::StaticProblem& problem, const std::string& casePath);

struct ShapeTerms {
  double position = 0.0, curvature = 0.0;  // C_r and C_k terms, unweighted by the case
  Eigen::VectorXd gradient;                // d(position + curvature)/dx, when asked
};

ShapeTerms shapeObjective(const mechanics::StaticProblem& problem, const std::vector<RodTarget>& targets,
                          const Eigen::VectorXd& x, double positionWeight, double curvatureWeight, bool gradient);

}  // namespace rodfab::optimize::detail
