#include "slam/loop/pose_graph.h"

#include <cmath>
#include <string>

#include <ceres/ceres.h>

#include "core/error.h"
#include "slam/loop/sim3_costs.h"

namespace cslam {

namespace {

void validate(const std::vector<PoseGraphNode>& nodes, const std::vector<PoseGraphEdge>& edges,
              const PoseGraphConfig& cfg) {
  if (cfg.max_iterations < 1) throw ConfigError("optimize_pose_graph: max_iterations must be >= 1");
  if (cfg.threads < 1) throw ConfigError("optimize_pose_graph: threads must be >= 1");
  const int n = int(nodes.size());
  for (int i = 0; i < n; ++i)
    if (!nodes[i].S_world_node.is_finite() || !(nodes[i].S_world_node.scale() > 0))
      throw ConfigError("optimize_pose_graph: node " + std::to_string(i) +
                        " has a non-finite pose or non-positive scale");
  for (size_t e = 0; e < edges.size(); ++e) {
    const auto& ed = edges[e];
    const std::string name = "optimize_pose_graph: edge " + std::to_string(e);
    if (ed.from < 0 || ed.from >= n || ed.to < 0 || ed.to >= n)
      throw ConfigError(name + " refers to a node outside [0, " + std::to_string(n) + ")");
    if (ed.from == ed.to) throw ConfigError(name + " connects node " + std::to_string(ed.from) + " to itself");
    if (!(ed.weight > 0) || !std::isfinite(ed.weight)) throw ConfigError(name + " has a non-positive weight");
    if (!ed.S_from_to.is_finite() || !(ed.S_from_to.scale() > 0))
      throw ConfigError(name + " has a non-finite measurement");
  }
}

}  // namespace

double pose_graph_edge_error(const Sim3& S_world_from, const Sim3& S_world_to, const PoseGraphEdge& edge,
                             bool fix_scale) {
  const Sim3Param a = to_sim3_param(S_world_from), b = to_sim3_param(S_world_to);
  double r[7] = {0, 0, 0, 0, 0, 0, 0};
  if (fix_scale)
    PoseGraphEdgeCost<6>(edge.S_from_to, edge.weight)(a.pose.data(), &a.log_scale, b.pose.data(), &b.log_scale, r);
  else
    PoseGraphEdgeCost<7>(edge.S_from_to, edge.weight)(a.pose.data(), &a.log_scale, b.pose.data(), &b.log_scale, r);
  double sq = 0;
  for (double v : r) sq += v * v;
  return sq;
}

PoseGraphResult optimize_pose_graph(const std::vector<PoseGraphNode>& nodes, const std::vector<PoseGraphEdge>& edges,
                                    const PoseGraphConfig& cfg) {
  validate(nodes, edges, cfg);
  PoseGraphResult res;
  for (const auto& n : nodes) res.S_world_node.push_back(n.S_world_node);
  if (edges.empty()) {
    res.converged = true;
    return res;
  }

  std::vector<Sim3Param> params;
  params.reserve(nodes.size());
  for (const auto& n : nodes) params.push_back(to_sim3_param(n.S_world_node));

  ceres::Problem problem;
  std::vector<char> used(nodes.size(), 0);
  for (const auto& e : edges) {
    ceres::CostFunction* cost =
        cfg.fix_scale
            ? static_cast<ceres::CostFunction*>(new ceres::AutoDiffCostFunction<PoseGraphEdgeCost<6>, 6, 6, 1, 6, 1>(
                  new PoseGraphEdgeCost<6>(e.S_from_to, e.weight)))
            : new ceres::AutoDiffCostFunction<PoseGraphEdgeCost<7>, 7, 6, 1, 6, 1>(
                  new PoseGraphEdgeCost<7>(e.S_from_to, e.weight));
    Sim3Param& a = params[e.from];
    Sim3Param& b = params[e.to];
    problem.AddResidualBlock(cost, nullptr, a.pose.data(), &a.log_scale, b.pose.data(), &b.log_scale);
    used[e.from] = used[e.to] = 1;
  }
  bool any_fixed = false;
  for (size_t i = 0; i < nodes.size(); ++i) any_fixed = any_fixed || (nodes[i].fixed && used[i]);
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (!used[i]) continue;
    const bool fixed = nodes[i].fixed || (!any_fixed && i == 0);
    if (fixed) problem.SetParameterBlockConstant(params[i].pose.data());
    if (fixed || cfg.fix_scale) problem.SetParameterBlockConstant(&params[i].log_scale);
  }
  // With no fixed node among the connected ones, hold the first connected node (gauge).
  if (!any_fixed && !used[0])
    for (size_t i = 0; i < nodes.size(); ++i)
      if (used[i]) {
        problem.SetParameterBlockConstant(params[i].pose.data());
        problem.SetParameterBlockConstant(&params[i].log_scale);
        break;
      }

  ceres::Solver::Options opts;
  opts.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  opts.max_num_iterations = cfg.max_iterations;
  opts.num_threads = cfg.threads;
  opts.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(opts, &problem, &summary);
  res.initial_cost = summary.initial_cost;
  res.final_cost = summary.final_cost;
  res.iterations = int(summary.iterations.size());
  res.converged = summary.termination_type == ceres::CONVERGENCE || summary.termination_type == ceres::NO_CONVERGENCE;
  if (res.converged)
    for (size_t i = 0; i < nodes.size(); ++i)
      if (used[i] && !nodes[i].fixed) res.S_world_node[i] = from_sim3_param(params[i].pose.data(), params[i].log_scale);
  return res;
}

}  // namespace cslam
