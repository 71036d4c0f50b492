// New map points from keyframe pairs: the two-view geometry (DLT or depth back-projection and its
// checks), the epipolar matcher, and the local-mapping step that creates the points, on synthetic
// views of known points.
#include <gtest/gtest.h>

#include "slam/mapping/synthetic_views.h"
#include "slam/mapping/triangulation.h"
#include "slam/match/triangulation_search.h"

using namespace cslam;

namespace {

struct TwoViews {
  TwoViews(int n, double baseline, std::function<bool(int)> depth1, std::function<bool(int)> depth2)
      : scene(make_scene(n, 7)), pyramid(ScalePyramid::from(OrbExtractor())) {
    T1 = SE3();
    T2 = SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY())),
             Eigen::Vector3d(-baseline, 0.02, 0.03));
    // View 2 lists the points in reverse: indices differ between the views.
    std::vector<int> rev = identity_order(n);
    std::reverse(rev.begin(), rev.end());
    order2 = rev;
    f1 = make_view(scene, T1, identity_order(n), depth1, pyramid);
    f2 = make_view(scene, T2, order2, depth2, pyramid);
  }
  int index2_of(int point) const { return int(order2.size()) - 1 - point; }
  Scene scene;
  std::shared_ptr<const ScalePyramid> pyramid;
  SE3 T1, T2;
  std::vector<int> order2;
  std::shared_ptr<const FrameData> f1, f2;
};

auto none = [](int) { return false; };
auto all = [](int) { return true; };

}  // namespace

TEST(Triangulation, MonocularPairWithParallaxGivesThePoint) {
  TwoViews v(50, 0.3, none, none);
  TriangulationConfig c;
  for (int p = 0; p < 50; ++p) {
    const auto x = triangulate_pair(*v.f1, v.T1, p, *v.f2, v.T2, v.index2_of(p), c);
    ASSERT_TRUE(x) << p;
    EXPECT_LT((*x - v.scene.points[p]).norm(), 1e-6) << p;
  }
}

TEST(Triangulation, DepthIsUsedWhenTheRaysHaveLessParallaxThanTheDepth) {
  // 1 cm apart: the rays' parallax is far below the depth's own virtual baseline.
  TwoViews v(30, 0.01, all, none);
  TriangulationConfig c;
  for (int p = 0; p < 30; ++p) {
    const auto x = triangulate_pair(*v.f1, v.T1, p, *v.f2, v.T2, v.index2_of(p), c);
    ASSERT_TRUE(x) << p;
    EXPECT_LT((*x - v.scene.points[p]).norm(), 1e-5) << p;
  }
  // Without depth the same pair is refused (too little parallax for a monocular point).
  TwoViews mono(30, 0.0005, none, none);
  int made = 0;
  for (int p = 0; p < 30; ++p)
    made += triangulate_pair(*mono.f1, mono.T1, p, *mono.f2, mono.T2, mono.index2_of(p), c).has_value();
  EXPECT_EQ(made, 0);
}

TEST(Triangulation, WrongCorrespondenceOrInconsistentDepthIsRefused) {
  TwoViews v(40, 0.3, none, none);
  TriangulationConfig c;
  int accepted = 0;
  for (int p = 0; p < 40; ++p)
    accepted += triangulate_pair(*v.f1, v.T1, p, *v.f2, v.T2, v.index2_of((p + 7) % 40), c).has_value();
  EXPECT_LE(accepted, 1);  // a wrong pair can only pass if it happens to lie on the epipolar line
  // A depth twice too far fails the virtual-right-coordinate check when the point comes from the
  // rays (its disparity is off by 5 px or more at these distances).
  auto bad = std::make_shared<FrameData>(*v.f1);
  for (std::size_t i = 0; i < bad->size(); ++i) {
    bad->depth[i] = float(2.0 * (v.T1 * v.scene.points[i]).z());
    bad->u_right[i] = float(bad->features.undistorted[i].x() - bad->rgbd.bf / bad->depth[i]);
  }
  accepted = 0;
  for (int p = 0; p < 40; ++p) accepted += triangulate_pair(*bad, v.T1, p, *v.f2, v.T2, v.index2_of(p), c).has_value();
  EXPECT_EQ(accepted, 0);
}

TEST(TriangulationSearch, FundamentalMatrixMapsPointsOntoTheirEpipolarLines) {
  TwoViews v(20, 0.3, none, none);
  const Eigen::Matrix3d F = fundamental_21(v.T1, v.f1->camera, v.T2, v.f2->camera);
  for (int p = 0; p < 20; ++p) {
    const Eigen::Vector2d a = v.f1->features.undistorted[p], b = v.f2->features.undistorted[v.index2_of(p)];
    const Eigen::Vector3d line = F * Eigen::Vector3d(a.x(), a.y(), 1);
    EXPECT_LT(std::abs(line.dot(Eigen::Vector3d(b.x(), b.y(), 1))) / line.head<2>().norm(), 1e-6);
  }
}

TEST(TriangulationSearch, FindsTheTruePairsAndRejectsOffEpipolarDescriptorTwins) {
  TwoViews v(60, 0.3, none, none);
  // Point 5 of view 2 gets point 4's descriptor: a descriptor twin off point 4's epipolar line.
  auto f2 = std::make_shared<FrameData>(*v.f2);
  f2->features.descriptors[v.index2_of(5)] = v.scene.descriptors[4];
  KeyFrame kf1(KeyFrameId{1, 0}, v.f1, v.T1), kf2(KeyFrameId{1, 1}, f2, v.T2);
  const auto pairs = search_for_triangulation(kf1, kf2);
  int right = 0, wrong = 0;
  for (const auto& [i1, i2] : pairs) (i2 == v.index2_of(i1) ? right : wrong)++;
  EXPECT_EQ(wrong, 0);
  EXPECT_GE(right, 58);  // all but (possibly) points 4 and 5
  // Keypoints that already have a map point take no part.
  kf1.map_points.set(10, std::make_shared<MapPoint>(MapPointId{1, 0}, v.scene.points[10], &kf1, cv::Vec3b()));
  for (const auto& [i1, i2] : search_for_triangulation(kf1, kf2)) EXPECT_NE(i1, 10);
}

TEST(CreateNewMapPoints, PointsOfAKeyframePairAreCreatedWithBothObservations) {
  // 40 shared points with depth connect the keyframes; 60 more without depth are to be triangulated.
  const int n = 100, linked = 40;
  TwoViews v(
      n, 0.3, [&](int k) { return k < linked; }, [&](int k) { return k >= n - linked; });
  Map map(1, 0, std::make_shared<IdAllocator>(1));
  auto kf1 = std::make_shared<KeyFrame>(map.ids().next_keyframe(), v.f1, v.T1);
  auto kf2 = std::make_shared<KeyFrame>(map.ids().next_keyframe(), v.f2, v.T2);
  map.add_keyframe(kf1);
  map.add_keyframe(kf2);
  for (int p = 0; p < linked; ++p) {
    auto mp = std::make_shared<MapPoint>(map.ids().next_map_point(), v.scene.points[p], kf1.get(), cv::Vec3b());
    Map::add_observation(kf1.get(), p, mp);
    Map::add_observation(kf2.get(), v.index2_of(p), mp);
    map.update_map_point(mp.get());
    map.add_map_point(mp);
  }
  map.update_connections(kf1.get());
  map.update_connections(kf2.get());
  ASSERT_EQ(kf2->weight(kf1.get()), linked);
  const auto created = create_new_map_points(map, kf2.get(), TriangulationConfig{});
  EXPECT_GE(int(created.size()), n - linked - 2);
  for (const auto& mp : created) {
    ASSERT_EQ(mp->observations.size(), 2u);
    const int i2 = mp->observations.at(kf2.get());
    const int p = int(v.order2[i2]);
    EXPECT_EQ(mp->observations.at(kf1.get()), p);
    EXPECT_LT((mp->position - v.scene.points[p]).norm(), 1e-6);
    EXPECT_EQ(kf1->map_points[p], mp);
    EXPECT_EQ(map.num_map_points(), std::size_t(linked) + created.size());
  }
  // Disabled: nothing.
  TriangulationConfig off;
  off.enabled = false;
  EXPECT_TRUE(create_new_map_points(map, kf2.get(), off).empty());
}
