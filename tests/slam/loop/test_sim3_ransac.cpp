// sim3_ransac: recovers a known SE3 and Sim3 from noisy matches with 50% wrong matches.
#include <gtest/gtest.h>

#include "core/error.h"
#include "geometry/alignment.h"
#include "loop_fixtures.h"

using namespace cslam;

namespace {

struct Case {
  const char* name;
  Sim3 S_12;
  bool fix_scale;
};

class Sim3RansacRecovers : public ::testing::TestWithParam<Case> {};

TEST_P(Sim3RansacRecovers, WithHalfOutliers) {
  const Case c = GetParam();
  const auto k = test::loop_intrinsics();
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    const auto set = test::make_matches(c.S_12, 300, 0.5, seed);
    Sim3RansacConfig cfg;
    cfg.fix_scale = c.fix_scale;
    cfg.seed = seed;
    const auto r = sim3_ransac(set.matches, k, k, cfg);
    ASSERT_TRUE(r.success) << c.name << " seed " << seed;
    ASSERT_EQ(r.inlier.size(), set.matches.size());
    EXPECT_LT(test::rotation_error_deg(r.S_12, c.S_12), 0.5) << c.name;
    EXPECT_LT((r.S_12.translation() - c.S_12.translation()).norm(), 0.03) << c.name;
    if (c.fix_scale)
      EXPECT_DOUBLE_EQ(r.S_12.scale(), 1.0);
    else
      EXPECT_NEAR(r.S_12.scale(), c.S_12.scale(), 0.02 * c.S_12.scale());
    int true_pos = 0, false_pos = 0, inliers = 0, count = 0;
    for (size_t i = 0; i < r.inlier.size(); ++i) {
      inliers += set.is_inlier[i];
      count += r.inlier[i];
      if (r.inlier[i]) (set.is_inlier[i] ? true_pos : false_pos)++;
    }
    EXPECT_EQ(count, r.num_inliers);
    EXPECT_GT(true_pos, 0.9 * inliers) << c.name;          // finds nearly all correct matches
    EXPECT_LT(false_pos, 0.03 * r.num_inliers) << c.name;  // and few wrong ones
    EXPECT_GE(r.iterations, 1);
    EXPECT_LE(r.iterations, cfg.max_iterations);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Loop, Sim3RansacRecovers,
    ::testing::Values(Case{"se3", test::rotation_about(0.35, {0.2, 1.0, 0.1}, {0.3, -0.1, 0.2}), true},
                      Case{"sim3", test::rotation_about(-0.3, {1.0, 0.4, -0.2}, {-0.2, 0.15, 0.4}, 1.4), false},
                      Case{"sim3_shrink", test::rotation_about(0.2, {0.0, 1.0, 0.3}, {0.1, 0.1, -0.1}, 0.7), false}),
    [](const ::testing::TestParamInfo<Case>& info) { return std::string(info.param.name); });

TEST(Sim3Ransac, FailsOnPureOutliersAndTooFewMatches) {
  const auto k = test::loop_intrinsics();
  const auto set = test::make_matches(test::rotation_about(0.3, {0, 1, 0}, {0.2, 0, 0}), 200, 1.0, 7);
  const auto r = sim3_ransac(set.matches, k, k);
  EXPECT_FALSE(r.success);
  EXPECT_LT(r.num_inliers, 20);
  EXPECT_EQ(r.iterations, 300);  // never found a good model, so it used every sample

  const auto few = test::make_matches(Sim3(), 10, 0.0, 8);
  const auto r2 = sim3_ransac(few.matches, k, k);  // fewer matches than min_inliers
  EXPECT_FALSE(r2.success);
  EXPECT_EQ(r2.inlier.size(), few.matches.size());
  EXPECT_FALSE(sim3_ransac({}, k, k).success);
}

TEST(Sim3Ransac, DeterministicForSeedAndStopsEarlyOnCleanData) {
  const auto k = test::loop_intrinsics();
  const auto set = test::make_matches(test::rotation_about(0.2, {1, 1, 0}, {0.1, 0.2, 0}), 150, 0.0, 9);
  Sim3RansacConfig cfg;
  const auto a = sim3_ransac(set.matches, k, k, cfg);
  const auto b = sim3_ransac(set.matches, k, k, cfg);
  ASSERT_TRUE(a.success);
  EXPECT_EQ(a.inlier, b.inlier);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_LT(a.iterations, 10);  // adaptive stopping: nearly all matches agree
}

TEST(Sim3Ransac, RejectsBadConfig) {
  const auto k = test::loop_intrinsics();
  Sim3RansacConfig cfg;
  cfg.probability = 1.0;
  EXPECT_THROW(sim3_ransac({}, k, k, cfg), ConfigError);
  cfg = {};
  cfg.max_iterations = 0;
  EXPECT_THROW(sim3_ransac({}, k, k, cfg), ConfigError);
  cfg = {};
  cfg.min_inliers = 2;
  EXPECT_THROW(sim3_ransac({}, k, k, cfg), ConfigError);
}

TEST(Sim3Ransac, MatchChi2IsZeroForExactMatchAndInfiniteBehind) {
  const auto k = test::loop_intrinsics();
  const Sim3 S = test::rotation_about(0.1, {0, 1, 0}, {0.1, 0, 0.05}, 1.2);
  Sim3Correspondence m;
  m.p2 = {0.2, -0.1, 2.0};
  m.p1 = S * m.p2;
  m.uv1 = test::project(k, m.p1);
  m.uv2 = test::project(k, m.p2);
  const auto e = sim3_match_chi2(S, m, k, k);
  EXPECT_NEAR(e.e1, 0, 1e-12);
  EXPECT_NEAR(e.e2, 0, 1e-12);
  m.p1.z() = -m.p1.z();
  EXPECT_TRUE(std::isinf(sim3_match_chi2(S, m, k, k).e2));
}

TEST(Alignment, PointerOverloadMatchesVectorOverload) {
  const Sim3 S = test::rotation_about(0.4, {1, 2, 3}, {1, -1, 0.5}, 2.0);
  std::vector<Eigen::Vector3d> src = {{0, 0, 1}, {1, 0, 2}, {0, 1, 3}, {1, 1, 1}}, dst;
  for (const auto& p : src) dst.push_back(S * p);
  const auto a = umeyama(src, dst, true);
  const auto b = umeyama(src.data(), dst.data(), 3, true);  // minimal sample
  ASSERT_TRUE(a.ok && b.ok);
  EXPECT_NEAR(a.T_dst_src.scale(), 2.0, 1e-9);
  EXPECT_NEAR(b.T_dst_src.scale(), 2.0, 1e-9);
  EXPECT_LT(b.T_dst_src.rotation().angularDistance(S.rotation()), 1e-9);
  EXPECT_FALSE(umeyama(src.data(), dst.data(), 2, true).ok);
}

}  // namespace
