#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "slam/features/feature_grid.h"
#include "slam/features/matching.h"
#include "slam/features/procedural_image.h"

namespace cslam {
namespace {

OrbFeatures random_features(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-5, 645), v(-5, 485);
  OrbFeatures f;
  for (int i = 0; i < n; ++i) {
    cv::KeyPoint kp(u(rng), v(rng), 31.f, 0.f, 1.f, int(rng() % 8));
    f.keypoints.push_back(kp);
    f.undistorted.emplace_back(kp.pt.x, kp.pt.y);
    f.descriptors.push_back({rng(), rng(), rng(), rng()});
  }
  return f;
}

TEST(FeatureGrid, RadiusQueryEqualsBruteForce) {
  const OrbFeatures f = random_features(3000, 1);
  const FeatureGrid grid(f, {0, 640, 0, 480});
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(-20, 660), v(-20, 500), r(0, 60);
  for (int q = 0; q < 300; ++q) {
    const double qu = u(rng), qv = v(rng), qr = r(rng);
    const int min_level = q % 3 == 0 ? -1 : int(rng() % 4), max_level = q % 5 == 0 ? -1 : min_level + 2;
    std::vector<int> expected;
    for (int i = 0; i < int(f.size()); ++i) {
      if (std::abs(f.undistorted[i].x() - qu) > qr || std::abs(f.undistorted[i].y() - qv) > qr) continue;
      if (min_level >= 0 && f.keypoints[i].octave < min_level) continue;
      if (max_level >= 0 && f.keypoints[i].octave > max_level) continue;
      expected.push_back(i);
    }
    ASSERT_EQ(grid.features_in_area(qu, qv, qr, min_level, max_level), expected) << "query " << q;
  }
  EXPECT_TRUE(FeatureGrid().features_in_area(10, 10, 5).empty());
  EXPECT_THROW(FeatureGrid(f, {0, 0, 0, 480}), std::invalid_argument);
}

TEST(RotationHistogram, KeepsThreeMostPopulatedBins) {
  RotationHistogram h(30);  // 12-degree bins
  int idx = 0;
  for (int i = 0; i < 20; ++i) h.add(5, 0, idx++);     // bin 0: 0..19
  for (int i = 0; i < 10; ++i) h.add(100, 50, idx++);  // bin 4: 20..29
  for (int i = 0; i < 3; ++i) h.add(0, 90, idx++);     // 270 deg -> bin 22: 30..32
  h.add(0, 200, idx++);                                // 160 deg -> bin 13: 33 (4th bin: outlier)
  h.add(0, 350, idx++);                                // 10 deg -> bin 0: 34
  std::vector<int> expected_out{33};
  EXPECT_EQ(h.outliers(), expected_out);
  EXPECT_EQ(h.inliers().size(), 34u);

  // A second/third bin below 10% of the first is dropped.
  RotationHistogram g(30);
  for (int i = 0; i < 100; ++i) g.add(0, 0, i);
  for (int i = 100; i < 109; ++i) g.add(60, 0, i);   // 9 < 10% of 100
  for (int i = 109; i < 120; ++i) g.add(120, 0, i);  // 11 >= 10%
  const std::vector<int> out = g.outliers();
  ASSERT_EQ(out.size(), 9u);
  EXPECT_EQ(out.front(), 100);
  EXPECT_EQ(out.back(), 108);
}

TEST(Matching, BestMatchAndSkip) {
  OrbFeatures f = random_features(5, 3);
  Descriptor q = f.descriptors[2];
  q[0] ^= 0x7;  // distance 3 to feature 2
  const std::vector<int> all{0, 1, 2, 3, 4};
  BestMatch m = best_match(q, f, all);
  EXPECT_EQ(m.index, 2);
  EXPECT_EQ(m.distance, 3);
  EXPECT_EQ(m.level, f.keypoints[2].octave);
  EXPECT_GT(m.second_distance, 60);  // random descriptors are ~128 apart
  std::vector<char> skip(5, 0);
  skip[2] = 1;
  EXPECT_NE(best_match(q, f, all, &skip).index, 2);
  EXPECT_EQ(best_match(q, f, {}).index, -1);
}

TEST(Matching, BruteForceFindsShiftedScene) {
  const cv::Mat img = procedural_image(31);
  cv::Mat shifted;
  const cv::Mat M = (cv::Mat_<double>(2, 3) << 1, 0, 25, 0, 1, -15);
  cv::warpAffine(img, shifted, M, img.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  const OrbExtractor ex;
  const OrbFeatures a = ex.extract(img), b = ex.extract(shifted);
  const std::vector<Match> m = match_brute_force(a, b, MatchParams{});
  ASSERT_GT(m.size(), 300u);
  int good = 0;
  std::vector<char> used(b.size(), 0);
  for (const Match& x : m) {
    ASSERT_FALSE(used[x.b]) << "b used twice";
    used[x.b] = 1;
    EXPECT_LE(x.distance, 50);
    const cv::Point2f d = b.keypoints[x.b].pt - a.keypoints[x.a].pt;
    good += std::hypot(d.x - 25, d.y + 15) < 4.0 * a.keypoints[x.a].size / 31.f;
  }
  EXPECT_GT(good, 0.95 * m.size());
  // Mask: only even a-indices.
  std::vector<char> mask(a.size(), 0);
  for (std::size_t i = 0; i < a.size(); i += 2) mask[i] = 1;
  for (const Match& x : match_brute_force(a, b, MatchParams{}, &mask)) EXPECT_EQ(x.a % 2, 0);
}

}  // namespace
}  // namespace cslam

namespace cslam {
namespace {

TEST(Matching, ByProjectionFindsShiftedFeatures) {
  // Project frame A's features into frame B with the known shift: each must find its twin.
  const cv::Mat img = procedural_image(41);
  cv::Mat shifted;
  const cv::Mat M = (cv::Mat_<double>(2, 3) << 1, 0, -12, 0, 1, 7);
  cv::warpAffine(img, shifted, M, img.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  const OrbExtractor ex;
  const OrbFeatures a = ex.extract(img), b = ex.extract(shifted);
  const FeatureGrid grid(b, {0, 640, 0, 480});
  std::vector<ProjectedDescriptor> points;
  for (std::size_t i = 0; i < a.size(); ++i)
    points.push_back({a.undistorted[i].x() - 12, a.undistorted[i].y() + 7, a.keypoints[i].octave, a.descriptors[i]});
  const auto m = match_by_projection(points, b, grid, ex.scale_factors(), 3.0, MatchParams{});
  ASSERT_GT(m.size(), 500u);
  std::vector<char> used(b.size(), 0);
  int good = 0;
  for (const Match& x : m) {
    ASSERT_FALSE(used[x.b]);
    used[x.b] = 1;
    EXPECT_LE(x.distance, 100);
    const double scale = ex.scale_factors()[a.keypoints[x.a].octave];
    EXPECT_LE(std::abs(b.undistorted[x.b].x() - points[x.a].u), 3.0 * scale + 1e-9);
    good += x.distance <= 50;
  }
  EXPECT_GT(good, 0.9 * m.size());
  // Taken features are never returned; a far-off projection finds nothing.
  std::vector<char> taken(b.size(), 1);
  EXPECT_TRUE(match_by_projection(points, b, grid, ex.scale_factors(), 3.0, MatchParams{}, &taken).empty());
  std::vector<ProjectedDescriptor> far{{-500, -500, 0, a.descriptors[0]}};
  EXPECT_TRUE(match_by_projection(far, b, grid, ex.scale_factors(), 3.0, MatchParams{}).empty());
}

}  // namespace
}  // namespace cslam
