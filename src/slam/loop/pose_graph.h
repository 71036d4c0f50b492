#pragma once
// Essential-graph / pose-graph optimisation over Sim3 (7-DoF) or SE3 (6-DoF) nodes with Ceres,
// as after a loop closure: nodes start from the (partly corrected) poses, edges carry measured
// relative transforms (spanning tree, strong covisibility, old and new loop edges).
// Node parameters: [angle-axis, translation] of S_world_node plus a log-scale block (constant
// when fix_scale). Edge residual, weighted by sqrt(weight):
//   E = S_from_to^-1 * S_world_from^-1 * S_world_to,  r = [angle-axis(R_E), t_E, log s_E]
// (7 residuals; 6 without the scale term when fix_scale). No robust kernel (edges are trusted).
// Solver: Levenberg-Marquardt, sparse normal Cholesky.
#include <vector>

#include "geometry/se3.h"

namespace cslam {

struct PoseGraphNode {
  Sim3 S_world_node;   // camera-to-world (scale 1 for SE3 graphs)
  bool fixed = false;  // held constant
};

struct PoseGraphEdge {
  int from = 0, to = 0;
  Sim3 S_from_to;       // measured S_world_from^-1 * S_world_to
  double weight = 1.0;  // multiplies the squared residual
};

struct PoseGraphConfig {
  int max_iterations = 20;
  bool fix_scale = true;  // true: SE3 graph (node scales kept as given), false: Sim3 graph
  int threads = 1;
};

struct PoseGraphResult {
  std::vector<Sim3> S_world_node;           // per node (fixed and unconnected nodes unchanged)
  double initial_cost = 0, final_cost = 0;  // 0.5 * sum of squared weighted residuals
  int iterations = 0;
  // The solver ended with a usable result: Ceres CONVERGENCE or NO_CONVERGENCE (max_iterations
  // reached, cost still decreased), as BaResult::converged. False on numerical failure.
  bool converged = false;
};

// Throws ConfigError on an edge with an out-of-range node, from == to, a non-positive or
// non-finite weight, a non-finite pose, max_iterations < 1 or threads < 1. If no node with an edge is fixed,
// the first node with an edge is held fixed (the gauge). An empty edge list returns the nodes
// unchanged. Nodes without edges keep their pose.
PoseGraphResult optimize_pose_graph(const std::vector<PoseGraphNode>& nodes, const std::vector<PoseGraphEdge>& edges,
                                    const PoseGraphConfig& cfg = {});

// Weighted squared residual norm of one edge at the given node poses (0 for a perfect edge).
double pose_graph_edge_error(const Sim3& S_world_from, const Sim3& S_world_to, const PoseGraphEdge& edge,
                             bool fix_scale);

}  // namespace cslam
