// Map::update_map_point: a point's distance bounds come from its reference observation's pyramid
// level, also when that observation changes (the level is kept between updates).
#include <cmath>

#include <gtest/gtest.h>

#include "common/fake_frame_data.h"
#include "slam/map/map.h"

using namespace cslam;

namespace {

using test::fake_frame_data;

// A keyframe centred at `center` (no rotation) whose keypoint i was detected at level `octave[i]`.
KeyFramePtr keyframe_at(Map& map, const std::shared_ptr<const ScalePyramid>& pyramid, const Eigen::Vector3d& center,
                        const std::vector<int>& octave) {
  auto data = std::make_shared<FrameData>(*fake_frame_data(int(octave.size()), pyramid));
  for (std::size_t i = 0; i < octave.size(); ++i) {
    data->features.keypoints[i].octave = octave[i];
    data->u_right[i] = 100.f;  // with depth: each observation counts twice
  }
  auto kf = std::make_shared<KeyFrame>(map.ids().next_keyframe(), data, SE3(Eigen::Quaterniond::Identity(), -center));
  map.add_keyframe(kf);
  return kf;
}

}  // namespace

TEST(MapPointUpdate, DistanceBoundsFollowTheReferenceObservation) {
  Map map(1, 0, std::make_shared<IdAllocator>(1));
  const auto pyramid = ScalePyramid::from(OrbExtractor());
  ASSERT_EQ(pyramid->num_levels, 8);
  const auto a = keyframe_at(map, pyramid, Eigen::Vector3d(0, 0, 0), {0, 0, 0, 2, 0, 0, 0});
  const auto b = keyframe_at(map, pyramid, Eigen::Vector3d(1, 0, 0), {0, 0, 0, 0, 0, 4, 1});
  const auto c = keyframe_at(map, pyramid, Eigen::Vector3d(0, 1, 0), {0, 3, 0, 0, 0, 0, 0});
  const auto d = keyframe_at(map, pyramid, Eigen::Vector3d(0, 0, 1), {5, 0, 0, 0, 0, 0, 0});
  auto mp = std::make_shared<MapPoint>(map.ids().next_map_point(), Eigen::Vector3d(0, 0, 2), a.get(), cv::Vec3b());
  map.add_map_point(mp);
  Map::add_observation(a.get(), 3, mp);
  Map::add_observation(b.get(), 5, mp);
  Map::add_observation(c.get(), 1, mp);
  Map::add_observation(d.get(), 0, mp);  // so that two observations can go without culling it
  const double top = pyramid->scale[7];
  auto expect_bounds = [&](double distance, int level, const char* what) {
    EXPECT_NEAR(mp->max_distance, distance * pyramid->scale[level], 1e-12) << what;
    EXPECT_NEAR(mp->min_distance, distance * pyramid->scale[level] / top, 1e-12) << what;
  };

  map.update_map_point(mp.get());
  expect_bounds(2.0, 2, "reference a, keypoint 3 at level 2");
  mp->position = Eigen::Vector3d(0, 0, 3);  // moved (a BA): the same level, the new distance
  map.update_map_point(mp.get());
  expect_bounds(3.0, 2, "the same observation after a move");

  map.erase_observation(a.get(), mp);  // the reference is gone: the first remaining one (b)
  map.update_map_point(mp.get());
  ASSERT_FALSE(mp->bad);
  EXPECT_EQ(mp->reference, b.get());
  expect_bounds(std::sqrt(10.0), 4, "reference b, keypoint 5 at level 4");

  // The same keyframe, another keypoint of it.
  map.erase_observation(b.get(), mp);
  Map::add_observation(b.get(), 6, mp);
  mp->reference = b.get();
  map.update_map_point(mp.get());
  expect_bounds(std::sqrt(10.0), 1, "reference b, keypoint 6 at level 1");

  mp->reference = c.get();
  map.update_map_point(mp.get());
  expect_bounds(std::sqrt(10.0), 3, "reference c, keypoint 1 at level 3");
}
