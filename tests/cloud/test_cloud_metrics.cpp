// Hausdorff / C2C / completeness on hand-made clouds with known distances, and bounding-box
// matching recovering a known scale and offset.
#include <gtest/gtest.h>

#include "cloud/cloud_metrics.h"

using namespace cslam;

namespace {

std::vector<Eigen::Vector3f> grid(int n, float spacing, float z) {
  std::vector<Eigen::Vector3f> pts;
  for (int x = 0; x < n; ++x)
    for (int y = 0; y < n; ++y) pts.emplace_back(spacing * x, spacing * y, z);
  return pts;
}

}  // namespace

TEST(CloudMetrics, NearestDistancesMatchBruteForce) {
  std::vector<Eigen::Vector3f> a, b;
  for (int i = 0; i < 300; ++i) {
    a.emplace_back(std::sin(i * 1.3f), std::cos(i * 0.7f), 0.01f * i);
    b.emplace_back(std::cos(i * 2.1f), std::sin(i * 0.3f), 0.012f * i);
  }
  const auto d = nearest_distances(a, b, 2);
  ASSERT_EQ(d.size(), a.size());
  for (size_t i = 0; i < a.size(); ++i) {
    float best = 1e9f;
    for (const auto& q : b) best = std::min(best, (a[i] - q).norm());
    EXPECT_NEAR(d[i], best, 1e-5f);
  }
}

TEST(CloudMetrics, FarQueriesAreExactToo) {
  // Dense targets (a 1 cm grid with a bump) and queries up to 2 m away: the far-query path
  // (coarse cells + member scan) must agree with brute force.
  std::vector<Eigen::Vector3f> targets;
  for (int x = 0; x < 120; ++x)
    for (int y = 0; y < 80; ++y)
      targets.emplace_back(0.01f * x, 0.01f * y, 0.05f * std::sin(0.1f * x) * std::cos(0.07f * y));
  std::vector<Eigen::Vector3f> queries;
  for (int i = 0; i < 400; ++i)
    queries.emplace_back(-1.0f + 0.0091f * i, 0.4f + std::sin(0.3f * i), 2.0f * std::cos(0.11f * i));
  const auto d = nearest_distances(queries, targets, 2);
  int far = 0;
  for (size_t i = 0; i < queries.size(); ++i) {
    float best = 1e9f;
    for (const auto& t : targets) best = std::min(best, (queries[i] - t).norm());
    EXPECT_NEAR(d[i], best, 1e-5f) << i;
    if (best > 0.5f) ++far;
  }
  EXPECT_GT(far, 100);
}

TEST(CloudMetrics, KnownDistancesOnShiftedPlane) {
  // REF: 20x20 grid (5 cm) at z = 0. TEST: the same grid at z = 0.01 plus one point 10 cm up.
  const auto ref = grid(20, 0.05f, 0.0f);
  auto test = grid(20, 0.05f, 0.01f);
  test.emplace_back(0.5f, 0.5f, 0.10f);
  const CloudComparison c = compare_clouds(ref, test);
  EXPECT_EQ(c.ref_points, 400u);
  EXPECT_EQ(c.test_points, 401u);
  EXPECT_NEAR(c.hausdorff_test_to_ref, 0.10, 1e-6);
  EXPECT_NEAR(c.hausdorff_ref_to_test, 0.01, 1e-6);
  EXPECT_NEAR(c.hausdorff_symmetric, 0.10, 1e-6);
  EXPECT_NEAR(c.test_to_ref.median, 0.01, 1e-6);
  EXPECT_NEAR(c.test_to_ref.p95, 0.01, 1e-6);
  EXPECT_NEAR(c.test_to_ref.mean, (400 * 0.01 + 0.10) / 401, 1e-6);
  EXPECT_NEAR(c.ref_to_test.mean, 0.01, 1e-6);
  ASSERT_EQ(c.completeness.size(), 2u);
  EXPECT_DOUBLE_EQ(c.completeness[0].first, 0.02);
  EXPECT_DOUBLE_EQ(c.completeness[0].second, 1.0);

  // Completeness counts REF points: move half of TEST 3 cm away -> half of REF lies beyond 2 cm.
  auto half = grid(20, 0.05f, 0.0f);
  for (size_t i = 0; i < half.size(); ++i)
    if (half[i].x() > 0.47f) half[i].z() = 0.03f;
  const CloudComparison h = compare_clouds(ref, half);
  EXPECT_NEAR(h.completeness[0].second, 0.5, 1e-9);  // within 2 cm
  EXPECT_NEAR(h.completeness[1].second, 1.0, 1e-9);  // within 5 cm
  EXPECT_NEAR(h.hausdorff_symmetric, 0.03, 1e-6);
}

TEST(CloudMetrics, BboxMatchingRecoversScaleAndOffset) {
  std::vector<Eigen::Vector3f> ref;
  for (int i = 0; i < 500; ++i) ref.emplace_back(std::sin(0.37f * i) * 2, std::cos(0.11f * i), 0.003f * i);
  const float s = 1.7f;
  const Eigen::Vector3f offset(1.0f, -2.0f, 3.0f);
  std::vector<Eigen::Vector3f> test;
  for (const auto& p : ref) test.push_back(s * p + offset);

  const BboxMatch m = compute_bbox_match(ref, test);
  EXPECT_NEAR(m.scale, 1.0 / s, 1e-5);
  for (size_t i = 0; i < ref.size(); i += 50) EXPECT_LT((m.apply(test[i]) - ref[i]).norm(), 1e-4f);

  const CloudComparison raw = compare_clouds(ref, test);
  EXPECT_GT(raw.hausdorff_symmetric, 1.0);
  CloudCompareConfig cfg;
  cfg.match_bbox = true;
  const CloudComparison matched = compare_clouds(ref, test, cfg);
  EXPECT_TRUE(matched.bbox_matched);
  EXPECT_LT(matched.hausdorff_symmetric, 1e-4);
  EXPECT_NEAR(matched.completeness[0].second, 1.0, 1e-12);
}

TEST(CloudMetrics, EmptyCloudsThrow) {
  EXPECT_THROW(compare_clouds({}, grid(2, 1, 0)), std::invalid_argument);
  EXPECT_THROW(compare_clouds(grid(2, 1, 0), {}), std::invalid_argument);
}
