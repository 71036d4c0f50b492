// Fusing duplicates in two steps, matched under the map's shared lock and written under the unique
// one (local mapping releases the lock in between): the two steps write what one fuse() writes, and
// a point that became bad or entered the keyframe between them is left as it is.
#include <gtest/gtest.h>

#include "slam/mapping/synthetic_views.h"
#include "slam/match/projection_search.h"

using namespace cslam;

namespace {

// kf1 and kf2 see the same points, with depth, kf2 from 5 cm aside. kf1 holds a map point for
// each; kf2 holds duplicates of its own (other points at the same places) for the first
// `duplicated` and nothing for the rest.
struct FuseScene {
  static constexpr int kPoints = 60, kDuplicated = 20;
  explicit FuseScene()
      : scene(make_scene(kPoints, 3)),
        pyramid(ScalePyramid::from(OrbExtractor())),
        map(1, 0, std::make_shared<IdAllocator>(1)) {
    const SE3 T1;
    const SE3 T2(Eigen::Quaterniond(Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY())), Eigen::Vector3d(-0.05, 0, 0));
    const auto all = [](int) { return true; };
    kf1 = std::make_shared<KeyFrame>(map.ids().next_keyframe(),
                                     make_view(scene, T1, identity_order(kPoints), all, pyramid), T1);
    kf2 = std::make_shared<KeyFrame>(map.ids().next_keyframe(),
                                     make_view(scene, T2, identity_order(kPoints), all, pyramid), T2);
    map.add_keyframe(kf1);
    map.add_keyframe(kf2);
    for (int p = 0; p < kPoints; ++p) {
      points.push_back(add_point(kf1.get(), p));
      duplicates.push_back(p < kDuplicated ? add_point(kf2.get(), p) : nullptr);
    }
  }
  MapPointPtr add_point(KeyFrame* kf, int p) {
    auto mp = std::make_shared<MapPoint>(map.ids().next_map_point(), scene.points[p], kf, cv::Vec3b());
    Map::add_observation(kf, p, mp);
    map.update_map_point(mp.get());
    map.add_map_point(mp);
    return mp;
  }
  bool in_view_2(int p) const {
    const auto& f = *kf2->data;
    const Eigen::Vector2d uv = f.camera.project(kf2->T_cam_world * scene.points[p]);
    return f.in_bounds(uv.x(), uv.y());
  }
  Scene scene;
  std::shared_ptr<const ScalePyramid> pyramid;
  Map map;
  KeyFramePtr kf1, kf2;
  std::vector<MapPointPtr> points, duplicates;
};

}  // namespace

TEST(Fuse, TwoStepsWriteWhatOneFuseWrites) {
  FuseScene one, two;
  const int fused_one = fuse(one.map, one.kf2.get(), one.points);
  const auto matches = match_for_fuse(two.kf2.get(), two.points);
  const int fused_two = apply_fuse(two.map, two.kf2.get(), matches);
  int in_view = 0;
  for (int p = 0; p < FuseScene::kPoints; ++p) in_view += one.in_view_2(p) ? 1 : 0;
  ASSERT_GE(in_view, 40);
  EXPECT_EQ(fused_one, in_view);
  EXPECT_EQ(fused_two, in_view);
  ASSERT_EQ(int(matches.size()), in_view);
  for (int p = 0; p < FuseScene::kPoints; ++p) {
    // A fused or added point: kf2's slot holds kf1's point (a duplicate has as many observations,
    // so kf1's survives), and the duplicate is gone.
    const bool seen = one.in_view_2(p);
    for (FuseScene* s : {&one, &two}) {
      EXPECT_EQ(s->kf2->map_points[p] == s->points[p], seen) << p;
      EXPECT_EQ(s->points[p]->in_keyframe(s->kf2.get()), seen) << p;
      if (s->duplicates[p]) {
        EXPECT_EQ(s->duplicates[p]->bad, seen) << p;
      }
    }
  }
  EXPECT_EQ(one.map.num_map_points(), two.map.num_map_points());
}

TEST(Fuse, AWriteBetweenTheStepsIsLeftAsItIs) {
  FuseScene s;
  const auto matches = match_for_fuse(s.kf2.get(), s.points);
  // Between the steps, another writer culls one point that kf2 lacks and adds another to kf2.
  int culled = -1, entered = -1;
  for (int p = FuseScene::kDuplicated; p < FuseScene::kPoints; ++p)
    if (s.in_view_2(p)) (culled < 0 ? culled : entered) = p;
  ASSERT_GE(culled, 0);
  ASSERT_GE(entered, 0);
  s.map.set_map_point_bad(s.points[culled]);
  Map::add_observation(s.kf2.get(), entered, s.points[entered]);
  EXPECT_EQ(apply_fuse(s.map, s.kf2.get(), matches), int(matches.size()) - 2);
  EXPECT_EQ(s.kf2->map_points[culled], nullptr);          // the culled point is not brought back
  EXPECT_EQ(s.points[entered]->observations.size(), 2u);  // observed once by kf2, as it was
  EXPECT_EQ(s.kf2->map_points[entered], s.points[entered]);
  // The rest is fused as without the writer.
  for (int p = 0; p < FuseScene::kDuplicated; ++p)
    if (s.in_view_2(p)) {
      EXPECT_EQ(s.kf2->map_points[p], s.points[p]) << p;
      EXPECT_TRUE(s.duplicates[p]->bad) << p;
    }
}
