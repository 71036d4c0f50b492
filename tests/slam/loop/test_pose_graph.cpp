// optimize_pose_graph: a drifted loop of 40 nodes closed by one true loop edge.
#include <gtest/gtest.h>

#include "core/error.h"
#include "loop_fixtures.h"

using namespace cslam;

namespace {

std::vector<Sim3> initial_poses(const test::DriftedGraph& g) {
  std::vector<Sim3> p;
  for (const auto& n : g.nodes) p.push_back(n.S_world_node);
  return p;
}

}  // namespace

TEST(PoseGraph, SE3LoopErrorIsDistributed) {
  const auto g = test::drifted_circle(40, 0.01, 1.0, 3);
  const double before = test::max_position_error(initial_poses(g), g.truth);
  ASSERT_GT(before, 1.0);  // the drifted chain really is off (metres)
  const double loop_before =
      pose_graph_edge_error(g.nodes.back().S_world_node, g.nodes[0].S_world_node, g.edges.back(), true);
  PoseGraphConfig cfg;
  const auto r = optimize_pose_graph(g.nodes, g.edges, cfg);
  ASSERT_TRUE(r.converged);
  ASSERT_EQ(r.S_world_node.size(), g.nodes.size());
  const double after = test::max_position_error(r.S_world_node, g.truth);
  EXPECT_LT(after, before / 5) << "before " << before << " after " << after;
  const double loop_after = pose_graph_edge_error(r.S_world_node.back(), r.S_world_node[0], g.edges.back(), true);
  EXPECT_LT(loop_after, 0.01 * loop_before);  // the loop closes
  EXPECT_LT(r.final_cost, 0.05 * r.initial_cost);
  EXPECT_GT(r.iterations, 1);
  // The fixed node is untouched and scales stay 1.
  EXPECT_EQ(r.S_world_node[0].translation(), g.nodes[0].S_world_node.translation());
  for (const auto& S : r.S_world_node) EXPECT_DOUBLE_EQ(S.scale(), 1.0);
}

TEST(PoseGraph, Sim3CorrectsScaleDriftThatSE3Cannot) {
  // Units shrink 1% per step: the integrated chain ends 47% too large.
  const auto g = test::drifted_circle(40, 0.01, 1.01, 4);
  const double before = test::max_position_error(initial_poses(g), g.truth);
  ASSERT_GT(before, 2.0);
  PoseGraphConfig cfg;
  cfg.fix_scale = false;
  const auto sim3 = optimize_pose_graph(g.nodes, g.edges, cfg);
  ASSERT_TRUE(sim3.converged);
  const double after = test::max_position_error(sim3.S_world_node, g.truth);
  EXPECT_LT(after, before / 5) << "before " << before << " after " << after;
  EXPECT_LT(pose_graph_edge_error(sim3.S_world_node.back(), sim3.S_world_node[0], g.edges.back(), false), 1e-3);
  // Node scales absorb the drift: the last node's units are 1.01^38 = 1.46 times too small.
  EXPECT_NEAR(sim3.S_world_node.back().scale(), 1.0 / g.edges.back().S_from_to.scale(), 0.1);
  EXPECT_DOUBLE_EQ(sim3.S_world_node[0].scale(), 1.0);

  // An SE3 graph on the same data (loop edge made rigid) cannot shrink the chain.
  std::vector<PoseGraphEdge> se3_edges = g.edges;
  se3_edges.back().S_from_to = Sim3(se3_edges.back().S_from_to.to_se3());
  cfg.fix_scale = true;
  const auto se3 = optimize_pose_graph(g.nodes, se3_edges, cfg);
  const double after_se3 = test::max_position_error(se3.S_world_node, g.truth);
  EXPECT_GT(after_se3, 3 * after) << "sim3 " << after << " se3 " << after_se3;
}

TEST(PoseGraph, FixedNodesStayAndWeightsMatter) {
  const auto g = test::drifted_circle(20, 0.02, 1.0, 5);
  auto nodes = g.nodes;
  nodes[10].fixed = true;  // a second anchor
  const auto r = optimize_pose_graph(nodes, g.edges);
  EXPECT_EQ(r.S_world_node[10].translation(), nodes[10].S_world_node.translation());
  EXPECT_EQ(r.S_world_node[10].rotation().coeffs(), nodes[10].S_world_node.rotation().coeffs());

  // A heavily weighted loop edge closes the loop tighter than a lightly weighted one.
  auto heavy = g.edges, light = g.edges;
  heavy.back().weight = 100.0;
  light.back().weight = 0.01;
  const auto rh = optimize_pose_graph(g.nodes, heavy);
  const auto rl = optimize_pose_graph(g.nodes, light);
  const auto loop = g.edges.back();
  EXPECT_LT(pose_graph_edge_error(rh.S_world_node.back(), rh.S_world_node[0], loop, true),
            pose_graph_edge_error(rl.S_world_node.back(), rl.S_world_node[0], loop, true));
}

TEST(PoseGraph, GaugeWithoutFixedNodeAndUnconnectedNodes) {
  auto g = test::drifted_circle(12, 0.02, 1.0, 6);
  g.nodes[0].fixed = false;
  g.nodes.push_back({test::rotation_about(0.3, {0, 0, 1}, {9, 9, 9}), false});  // no edge
  const auto r = optimize_pose_graph(g.nodes, g.edges);
  ASSERT_TRUE(r.converged);
  EXPECT_LT((r.S_world_node[0].translation() - g.nodes[0].S_world_node.translation()).norm(), 1e-12);  // gauge
  EXPECT_EQ(r.S_world_node.back().translation(), g.nodes.back().S_world_node.translation());
  EXPECT_LT(r.final_cost, 0.1 * r.initial_cost);
}

TEST(PoseGraph, EmptyAndInvalidInput) {
  const auto g = test::drifted_circle(5, 0.0, 1.0, 7);
  const auto r = optimize_pose_graph(g.nodes, {});
  EXPECT_EQ(r.S_world_node.size(), 5u);
  auto bad = g.edges;
  bad[0].to = 5;
  EXPECT_THROW(optimize_pose_graph(g.nodes, bad), ConfigError);
  bad = g.edges;
  bad[0].to = bad[0].from;
  EXPECT_THROW(optimize_pose_graph(g.nodes, bad), ConfigError);
  bad = g.edges;
  bad[1].weight = 0;
  EXPECT_THROW(optimize_pose_graph(g.nodes, bad), ConfigError);
  PoseGraphConfig cfg;
  cfg.max_iterations = 0;
  EXPECT_THROW(optimize_pose_graph(g.nodes, g.edges, cfg), ConfigError);
  cfg = {};
  cfg.threads = 0;
  EXPECT_THROW(optimize_pose_graph(g.nodes, g.edges, cfg), ConfigError);
}
