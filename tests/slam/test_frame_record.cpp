// Frame records follow culled reference keyframes up the spanning tree, and re-anchoring them
// frees the culled keyframes (4 robots revisiting a room for 10 min: the server's heap grew by
// ~2 MB/s while every culled keyframe stayed alive through the frames tracked against it).
#include <gtest/gtest.h>

#include "common/fake_frame_data.h"
#include "slam/features/orb_extractor.h"
#include "slam/frame_record.h"

using namespace cslam;

namespace {

SE3 pose(double x, double yaw) {
  return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(x, 0.1 * x, 0));
}

KeyFramePtr keyframe(std::uint32_t seq, const SE3& T_cam_world) {
  const auto pyramid = ScalePyramid::from(OrbExtractor());
  return std::make_shared<KeyFrame>(KeyFrameId{1, seq}, test::fake_frame_data(50, pyramid), T_cam_world);
}

// What Map::erase_keyframe does to a culled keyframe's pose chain.
void cull(KeyFrame& kf) {
  kf.T_cam_parent = kf.T_cam_world * kf.parent->T_world_cam();
  kf.bad = true;
}

}  // namespace

TEST(FrameRecord, CulledChainIsFollowedAndThenFreed) {
  KeyFramePtr root = keyframe(1, pose(0, 0)), mid = keyframe(2, pose(0.3, 0.2)), leaf = keyframe(3, pose(0.5, -0.1));
  mid->parent = root;
  leaf->parent = mid;
  std::vector<FrameRecord> records{{1.0, leaf, pose(0.05, 0.01), 0}, {2.0, root, pose(0.02, 0.0), 0}};
  const SE3 T_cam_world = records[0].T_cam_ref * leaf->T_cam_world;
  cull(*leaf);
  cull(*mid);
  std::weak_ptr<KeyFrame> weak_leaf = leaf, weak_mid = mid;
  leaf.reset();
  mid.reset();
  // Before: the frame's pose through the chain of culled keyframes, which stay alive.
  const LiveReference before = live_reference(records[0]);
  ASSERT_EQ(before.keyframe, root.get());
  const SE3 T_before = before.T_cam_ref * root->T_cam_world;
  EXPECT_LT((T_before.translation() - T_cam_world.translation()).norm(), 1e-12);
  EXPECT_FALSE(weak_leaf.expired());
  reanchor_culled(records);
  // After: the record refers to the live root with the same (bit-identical) relative pose, and
  // the culled keyframes are gone.
  EXPECT_EQ(records[0].reference, root);
  EXPECT_EQ(records[0].T_cam_ref.translation(), before.T_cam_ref.translation());
  EXPECT_EQ(records[0].T_cam_ref.rotation().coeffs(), before.T_cam_ref.rotation().coeffs());
  EXPECT_TRUE(weak_leaf.expired());
  EXPECT_TRUE(weak_mid.expired());
  EXPECT_EQ(records[1].reference, root);  // live references untouched
  EXPECT_EQ(live_reference(records[0]).keyframe, root.get());
}

TEST(FrameRecord, CulledRootWithoutParentStays) {
  KeyFramePtr root = keyframe(1, pose(0, 0));
  std::vector<FrameRecord> records{{1.0, root, SE3(), 0}};
  root->bad = true;  // no parent to move to
  reanchor_culled(records);
  EXPECT_EQ(records[0].reference, root);
  EXPECT_EQ(live_reference(records[0]).keyframe, root.get());
}
