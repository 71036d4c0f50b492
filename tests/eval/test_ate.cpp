#include <cmath>

#include <gtest/gtest.h>

#include "core/error.h"
#include "eval/trajectory_eval.h"

using namespace cslam;

namespace {
Trajectory circle(int n) {
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    const double a = 0.05 * i;
    t.push_back({100.0 + i / 30.0, SE3(Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ())),
                                       Eigen::Vector3d(2 * std::cos(a), 2 * std::sin(a), 0.3 * std::sin(3 * a)))});
  }
  return t;
}
}  // namespace

TEST(Ate, RigidlyMovedEstimateHasZeroErrorAfterAlignment) {
  const Trajectory gt = circle(200);
  const SE3 offset(Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Eigen::Vector3d(0.3, 0.4, 1).normalized())),
                   Eigen::Vector3d(5, -3, 1));
  Trajectory est = gt;
  for (auto& p : est) p.T_world_cam = offset * p.T_world_cam;
  EXPECT_LT(compute_ate(gt, est, Alignment::kSE3).stats.rmse, 1e-9);
  EXPECT_GT(compute_ate(gt, est, Alignment::kNone).stats.rmse, 1.0);
}

TEST(Ate, PerturbedGroundTruthMatchesAnalyticValue) {
  // Offsets of +-d along z alternating: zero mean, so the optimal alignment is the identity and
  // every error is exactly d: rmse = mean = max = min = d, std = 0.
  const Trajectory gt = circle(300);
  const double d = 0.05;
  Trajectory est = gt;
  for (size_t i = 0; i < est.size(); ++i)
    est[i].T_world_cam =
        SE3(est[i].T_world_cam.rotation(), est[i].T_world_cam.translation() + Eigen::Vector3d(0, 0, i % 2 ? d : -d));
  const auto r = compute_ate(gt, est, Alignment::kNone);
  EXPECT_EQ(r.stats.n, 300);
  EXPECT_NEAR(r.stats.rmse, d, 1e-9);
  EXPECT_NEAR(r.stats.max, d, 1e-9);
  EXPECT_NEAR(r.stats.std, 0.0, 1e-9);
  const auto aligned = compute_ate(gt, est, Alignment::kSE3);
  EXPECT_NEAR(aligned.stats.rmse, d, 1e-3);

  // A scaled copy: sim3 alignment removes the scale, se3 does not.
  Trajectory scaled = gt;
  for (auto& p : scaled) p.T_world_cam = SE3(p.T_world_cam.rotation(), 2.0 * p.T_world_cam.translation());
  const auto s = compute_ate(gt, scaled, Alignment::kSim3);
  EXPECT_LT(s.stats.rmse, 1e-9);
  EXPECT_NEAR(s.T_gt_est.scale(), 0.5, 1e-9);
  EXPECT_GT(compute_ate(gt, scaled, Alignment::kSE3).stats.rmse, 0.1);
}

TEST(Ate, TooFewAssociatedPosesIsAnError) {
  const Trajectory gt = circle(10);
  Trajectory est = gt;
  for (auto& p : est) p.timestamp += 10.0;
  EXPECT_THROW(compute_ate(gt, est, Alignment::kSE3), InputError);
}

TEST(Rpe, ConstantDriftGivesKnownRelativeError) {
  const Trajectory gt = circle(300);
  Trajectory est = gt;
  // Identical trajectories: zero RPE.
  auto r0 = compute_rpe(gt, est, 1.0);
  EXPECT_LT(r0.translation.rmse, 1e-9);
  EXPECT_LT(r0.rotation.rmse, 1e-6);
  EXPECT_GT(r0.translation.n, 200);
}
