// The seam of a fusion (the same points found in both maps, cross-map covisibility) and the
// group's global BA over both maps with the linked points as one.
#include <algorithm>
#include <map>

#include <gtest/gtest.h>

#include "common/map_checks.h"
#include "eval/trajectory_eval.h"
#include "fusion/fusion_manager.h"
#include "fusion/seam.h"
#include "slam/loop/global_ba.h"
#include "slam/map/map_locks.h"
#include "two_maps_fixture.h"

using namespace cslam;

namespace {

using UniqueLocks = std::vector<std::unique_lock<std::shared_mutex>>;
using SharedLocks = std::vector<std::shared_lock<std::shared_mutex>>;

// The keyframe pair (one per map) closest in ground truth: near centres, similar viewing direction.
std::pair<KeyFramePtr, KeyFramePtr> closest_pair(const test::ClientMap& a, const test::ClientMap& b) {
  double best = 1e9;
  std::pair<KeyFramePtr, KeyFramePtr> out;
  for (const auto& ka : a.map->keyframes())
    for (const auto& kb : b.map->keyframes()) {
      const auto pa = interpolate_pose(a.groundtruth, ka->timestamp());
      const auto pb = interpolate_pose(b.groundtruth, kb->timestamp());
      if (!pa || !pb) continue;
      const SE3 d = pa->inverse() * *pb;
      const double score = d.translation().norm() + 0.02 * d.rotation_angle() * 180 / M_PI;
      if (score < best) {
        best = score;
        out = {ka, kb};
      }
    }
  return out;
}

// Accuracy of the two maps' keyframes together, one SE3 alignment to ground truth (the combined
// trajectory of a fused group): grows with any misalignment between the maps.
double joint_keyframe_ate(const test::ClientMap& a, const test::ClientMap& b) {
  SharedLocks locks = lock_maps<std::shared_lock<std::shared_mutex>>({a.map.get(), b.map.get()});
  return compute_ate_joint(
             {{a.groundtruth, test::keyframe_trajectory(*a.map)}, {b.groundtruth, test::keyframe_trajectory(*b.map)}},
             Alignment::kSE3, 0.001)
      .stats.rmse;
}

SE3 small_error() {
  return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.25 * M_PI / 180, Eigen::Vector3d(0.3, 1, 0.2).normalized())),
             Eigen::Vector3d(0.008, -0.006, 0.004));
}

}  // namespace

TEST(Seam, LinksTheSamePointsAcrossMapsAndGroupBaRemovesTheMisalignment) {
  test::TempDir dir("cslam_seam");
  test::TwoMaps m = test::build_two_maps(dir);
  // Map b into map a's frame (as a fusion does), with a small error left.
  const SE3 T_a_b = m.a.T_gtworld_map.inverse() * m.b.T_gtworld_map;
  transform_map(*m.b.map, T_a_b);
  // What the two maps' own errors give when they are exactly aligned, then with the error.
  const double aligned = joint_keyframe_ate(m.a, m.b);
  transform_map(*m.b.map, small_error());
  const double before = joint_keyframe_ate(m.a, m.b);

  Seam seam;
  std::map<const MapPoint*, Eigen::Vector3d> old_position;
  {
    UniqueLocks locks = lock_maps<std::unique_lock<std::shared_mutex>>({m.a.map.get(), m.b.map.get()});
    const auto [ka, kb] = closest_pair(m.a, m.b);
    ASSERT_TRUE(ka && kb);
    for (const auto& mp : m.b.map->map_points()) old_position[mp.get()] = mp->position;
    seam = connect_seam(*m.a.map, *ka, *m.b.map, *kb);
  }
  // Linked pairs are the same physical points: close before linking (within what two maps of
  // 320x240 images place a point apart: ~1 cm per pixel at 3 m), identical after.
  ASSERT_GE(seam.points.size(), 40u);
  std::vector<double> gaps;
  for (const auto& l : seam.points) {
    EXPECT_NE(l.kept.get(), l.moved.get());
    EXPECT_EQ(l.moved->position, l.kept->position);
    gaps.push_back((old_position.at(l.moved.get()) - l.kept->position).norm());
  }
  std::sort(gaps.begin(), gaps.end());
  EXPECT_LT(gaps[gaps.size() / 2], 0.05);
  EXPECT_LT(gaps[gaps.size() * 9 / 10], 0.12);
  ASSERT_FALSE(seam.edges.empty());
  for (const auto& e : seam.edges) {
    EXPECT_GE(e.weight, 15);
    EXPECT_EQ(e.kept->id.client, 1);
    EXPECT_EQ(e.moved->id.client, 2);
  }

  // Global BA over both maps, the linked pairs estimated as one point.
  GlobalBa gba;
  std::vector<std::pair<MapPointPtr, MapPointPtr>> links;
  for (const auto& l : seam.points) links.emplace_back(l.kept, l.moved);
  {
    SharedLocks locks = lock_maps<std::shared_lock<std::shared_mutex>>({m.a.map.get(), m.b.map.get()});
    gba.snapshot({m.a.map.get(), m.b.map.get()}, links);
  }
  const BaResult r = gba.solve(10, nullptr);
  {
    UniqueLocks locks = lock_maps<std::unique_lock<std::shared_mutex>>({m.a.map.get(), m.b.map.get()});
    ASSERT_TRUE(gba.apply(r));
    test::expect_consistent(*m.a.map);
    test::expect_consistent(*m.b.map);
    for (const auto& l : seam.points) EXPECT_LT((l.moved->position - l.kept->position).norm(), 1e-9);
  }
  const double after = joint_keyframe_ate(m.a, m.b);
  std::printf(
      "joint keyframe ATE exactly aligned %.4f m, misaligned (before group BA) %.4f m, after %.4f m; link gaps "
      "median %.4f p90 %.4f\n",
      aligned, before, after, gaps[gaps.size() / 2], gaps[gaps.size() * 9 / 10]);
  // The group BA removes most of what the misalignment added to the maps' own error.
  ASSERT_GT(before, aligned);
  EXPECT_LT(after - aligned, 0.5 * (before - aligned));
}

TEST(Seam, GroupBaIsDiscardedWhenAMapChangedMeanwhile) {
  test::TempDir dir("cslam_seam_discard");
  test::TwoMaps m = test::build_two_maps(dir);
  GlobalBa gba;
  {
    SharedLocks locks = lock_maps<std::shared_lock<std::shared_mutex>>({m.a.map.get(), m.b.map.get()});
    gba.snapshot({m.a.map.get(), m.b.map.get()});
  }
  const BaResult r = gba.solve(3, nullptr);
  std::map<const KeyFrame*, SE3> poses;
  {
    UniqueLocks locks = lock_maps<std::unique_lock<std::shared_mutex>>({m.a.map.get(), m.b.map.get()});
    m.b.map->note_big_change();  // e.g. client 2 closed a loop while the BA solved
    for (const auto& kf : m.a.map->keyframes()) poses[kf.get()] = kf->T_cam_world;
    EXPECT_FALSE(gba.apply(r));
    for (const auto& kf : m.a.map->keyframes())
      EXPECT_TRUE(kf->T_cam_world.translation() == poses.at(kf.get()).translation())
          << "map a written by a discarded BA";
  }
}
