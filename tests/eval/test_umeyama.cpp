#include <random>

#include <gtest/gtest.h>

#include "eval/trajectory_eval.h"

using namespace cslam;

namespace {
std::vector<Eigen::Vector3d> random_points(int n, int seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-2, 2);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < n; ++i) pts.emplace_back(u(rng), u(rng), u(rng));
  return pts;
}
}  // namespace

TEST(Umeyama, RecoversSim3AndSE3) {
  const Sim3 truth(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized())),
                   Eigen::Vector3d(0.4, -1.1, 2.3), 1.8);
  const auto src = random_points(50, 3);
  std::vector<Eigen::Vector3d> dst;
  for (const auto& p : src) dst.push_back(truth * p);
  const auto r = umeyama(src, dst, true);
  ASSERT_TRUE(r.ok);
  EXPECT_NEAR(r.T_dst_src.scale(), 1.8, 1e-9);
  EXPECT_LT(r.T_dst_src.rotation().angularDistance(truth.rotation()), 1e-9);
  EXPECT_LT((r.T_dst_src.translation() - truth.translation()).norm(), 1e-9);

  const Sim3 rigid(truth.rotation(), truth.translation(), 1.0);
  dst.clear();
  for (const auto& p : src) dst.push_back(rigid * p);
  const auto r2 = umeyama(src, dst, false);
  ASSERT_TRUE(r2.ok);
  EXPECT_DOUBLE_EQ(r2.T_dst_src.scale(), 1.0);
  EXPECT_LT(r2.rmse, 1e-9);
}

TEST(Umeyama, DegenerateInput) {
  std::vector<Eigen::Vector3d> same(5, Eigen::Vector3d(1, 2, 3));
  EXPECT_FALSE(umeyama(same, same, true).ok);
  EXPECT_FALSE(umeyama({}, {}, false).ok);
}
