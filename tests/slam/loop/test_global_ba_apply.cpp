// GlobalBa::apply_map with a keyframe created while the BA solved: the keyframe keeps its pose
// relative to its optimised anchor, the points it references follow it, and a point the BA
// optimised takes the BA's value even when its reference is now the new keyframe.
#include <gtest/gtest.h>

#include "slam/loop/global_ba.h"
#include "slam/mapping/synthetic_views.h"

using namespace cslam;

namespace {

// kf0 (the origin, fixed) and kf1 see 60 points with depth; kf1 starts 3 cm off, so the BA moves
// it. After the snapshot, kf2 is created with kf1 as its parent; it sees point 0 (an optimised
// point) and holds one new point of its own.
struct Scene3 {
  explicit Scene3(bool reference_moves_to_new)
      : scene(make_scene(60, 5)),
        pyramid(ScalePyramid::from(OrbExtractor())),
        map(1, 0, std::make_shared<IdAllocator>(1)) {
    const auto all = [](int) { return true; };
    const SE3 T0, T1_true(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.2, 0, 0));
    kf0 = std::make_shared<KeyFrame>(map.ids().next_keyframe(), make_view(scene, T0, identity_order(60), all, pyramid),
                                     T0);
    kf1 = std::make_shared<KeyFrame>(map.ids().next_keyframe(),
                                     make_view(scene, T1_true, identity_order(60), all, pyramid),
                                     SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.2, 0.03, 0)));
    map.add_keyframe(kf0);
    map.add_keyframe(kf1);
    for (int p = 0; p < 60; ++p) {
      auto mp = std::make_shared<MapPoint>(map.ids().next_map_point(), scene.points[p], kf0.get(), cv::Vec3b());
      Map::add_observation(kf0.get(), p, mp);
      Map::add_observation(kf1.get(), p, mp);
      map.update_map_point(mp.get());
      map.add_map_point(mp);
      points.push_back(mp);
    }
    gba.snapshot({&map});
    // Meanwhile: kf2, 10 cm beside kf1, its parent; it sees point 0 and holds a new point.
    const SE3 T12(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.1, 0, 0));
    kf2 = std::make_shared<KeyFrame>(map.ids().next_keyframe(), kf1->data, T12 * kf1->T_cam_world);
    kf2->parent = kf1;
    map.add_keyframe(kf2);
    Map::add_observation(kf2.get(), 0, points[0]);
    if (reference_moves_to_new) points[0]->reference = kf2.get();
    fresh = std::make_shared<MapPoint>(map.ids().next_map_point(), kf2->T_world_cam() * Eigen::Vector3d(0.1, 0.2, 2.0),
                                       kf2.get(), cv::Vec3b());
    Map::add_observation(kf2.get(), 1, fresh);
    map.add_map_point(fresh);
  }
  Scene scene;
  std::shared_ptr<const ScalePyramid> pyramid;
  Map map;
  KeyFramePtr kf0, kf1, kf2;
  std::vector<MapPointPtr> points;
  MapPointPtr fresh;
  GlobalBa gba;
};

}  // namespace

TEST(GlobalBaApply, KeyframesCreatedMeanwhileCarryTheirPointsAndOptimisedPointsKeepTheBasValue) {
  Scene3 moved(true), kept(false);
  const SE3 T_21_before = moved.kf2->T_cam_world * moved.kf1->T_world_cam();
  const Eigen::Vector3d fresh_in_2 = moved.kf2->T_cam_world * moved.fresh->position;
  const Eigen::Vector3d kf1_before = moved.kf1->center();
  for (Scene3* s : {&moved, &kept}) {
    const BaResult r = s->gba.solve(10, nullptr);
    ASSERT_TRUE(s->gba.apply_map(0, r));
  }
  // The BA moved kf1 back toward its true place (3 cm off before).
  EXPECT_GT((moved.kf1->center() - kf1_before).norm(), 0.02);
  // kf2 followed kf1, and its own new point followed kf2.
  const SE3 T_21_after = moved.kf2->T_cam_world * moved.kf1->T_world_cam();
  EXPECT_LT((T_21_after.translation() - T_21_before.translation()).norm(), 1e-9);
  EXPECT_LT((moved.kf2->T_cam_world * moved.fresh->position - fresh_in_2).norm(), 1e-9);
  // Point 0 was optimised: it has the BA's value whether or not its reference is now kf2.
  EXPECT_LT((moved.points[0]->position - kept.points[0]->position).norm(), 1e-12);
  EXPECT_LT((moved.points[0]->position - moved.scene.points[0]).norm(), 1e-3);
}
