#include <gtest/gtest.h>

#include "common/fake_frame_data.h"
#include "slam/loop/essential_graph.h"

using namespace cslam;

using test::fake_frame_data;

TEST(EssentialGraph, SpanningTreeLoopStrongCovisibilityAndNewLinks) {
  Map map(1, 0, std::make_shared<IdAllocator>(1));
  auto pyr = ScalePyramid::from(OrbExtractor());
  std::vector<KeyFramePtr> kfs;
  for (int i = 0; i < 5; ++i) {
    kfs.push_back(std::make_shared<KeyFrame>(map.ids().next_keyframe(), fake_frame_data(400, pyr),
                                             SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1 * i, 0, 0))));
    map.add_keyframe(kfs.back());
  }
  auto share = [&](int a, int b, int first, int count) {
    for (int i = first; i < first + count; ++i) {
      auto mp =
          std::make_shared<MapPoint>(map.ids().next_map_point(), Eigen::Vector3d(0, 0, 1), kfs[a].get(), cv::Vec3b());
      map.add_map_point(mp);
      Map::add_observation(kfs[a].get(), i, mp);
      Map::add_observation(kfs[b].get(), i, mp);
    }
  };
  // Keyframes are connected as they are inserted, in order (as local mapping does).
  share(0, 1, 0, 150);  // strong: 150 >= 100
  map.update_connections(kfs[1].get());
  share(1, 2, 150, 40);  // weak: tree only
  map.update_connections(kfs[2].get());
  share(2, 3, 190, 40);
  share(1, 3, 270, 20);  // weak covisibility, not in the tree
  map.update_connections(kfs[3].get());
  share(3, 4, 230, 40);
  map.update_connections(kfs[4].get());
  ASSERT_EQ(kfs[3]->parent, kfs[2]);
  kfs[4]->loop_edges.insert(kfs[0].get());
  kfs[0]->loop_edges.insert(kfs[4].get());

  EssentialGraphInput in;
  in.new_connections[kfs[4].get()].insert(kfs[1].get());
  in.initial_T_cam_world[kfs[4].get()] = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.05, 0, 0));
  in.fixed.insert(kfs[0].get());
  const EssentialGraph g = build_essential_graph(map, in);

  ASSERT_EQ(g.nodes.size(), 5u);
  EXPECT_TRUE(g.nodes[g.index.at(kfs[0].get())].fixed);
  EXPECT_FALSE(g.nodes[g.index.at(kfs[2].get())].fixed);
  // Initial pose override: node 4 starts at the corrected pose (camera-to-world = inverse).
  EXPECT_NEAR(g.nodes[g.index.at(kfs[4].get())].S_world_node.translation().x(), -0.05, 1e-12);
  // Tree 0-1-2-3-4; 0-1 is also the only strong covisibility edge and is counted once (kf 0 is
  // visited first, so as covisibility).
  EXPECT_EQ(g.spanning_edges, 3);
  EXPECT_EQ(g.covisibility_edges, 1);
  EXPECT_EQ(g.loop_edges, 1);
  EXPECT_EQ(g.new_loop_edges, 1);
  // 0-1 (150 shared) is both tree and strong covisibility: one edge. 1-3 (20) is neither.
  int edges_13 = 0;
  for (const auto& e : g.edges) {
    const auto pair = std::minmax(g.keyframes[e.from], g.keyframes[e.to]);
    if (pair == std::minmax(kfs[1].get(), kfs[3].get())) ++edges_13;
  }
  EXPECT_EQ(edges_13, 0);
  EXPECT_EQ(g.edges.size(), size_t(g.spanning_edges + g.loop_edges + g.covisibility_edges + g.new_loop_edges));
  // Edges measure the relative pose between the endpoints' measured poses.
  for (const auto& e : g.edges) {
    if (g.keyframes[e.from] == kfs[4].get() || g.keyframes[e.to] == kfs[4].get()) continue;
    const Sim3 expected = g.nodes[e.from].S_world_node.inverse() * g.nodes[e.to].S_world_node;
    EXPECT_LT((e.S_from_to.translation() - expected.translation()).norm(), 1e-12);
  }
}
