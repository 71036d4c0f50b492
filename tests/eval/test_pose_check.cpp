// Relative-pose checks against interpolated ground truth and the time-offset estimate.
#include <cmath>

#include <gtest/gtest.h>

#include "core/error.h"
#include "eval/pose_check.h"

using namespace cslam;

namespace {

// A camera turning fast about a wobbling axis while moving, sampled at `rate` Hz from t0.
SE3 motion(double t) {
  const Eigen::Vector3d axis = Eigen::Vector3d(std::sin(t), 1.0, 0.3 * std::cos(2 * t)).normalized();
  const Eigen::Quaterniond q(Eigen::AngleAxisd(1.2 * std::sin(1.7 * t), axis));
  return SE3(q, Eigen::Vector3d(0.3 * std::sin(t), 0.2 * t, 0.1 * std::cos(3 * t)));
}

Trajectory sampled(double t0, double t1, double rate, double shift = 0) {
  Trajectory out;
  for (double t = t0; t <= t1; t += 1.0 / rate) out.push_back({t - shift, motion(t)});
  return out;
}

}  // namespace

TEST(PoseCheck, InterpolationIsExactAtSamplesAndCloseBetween) {
  const Trajectory gt = sampled(0, 5, 100);
  const auto at = interpolate_pose(gt, gt[10].timestamp);
  ASSERT_TRUE(at.has_value());
  EXPECT_LT((at->translation() - gt[10].T_world_cam.translation()).norm(), 1e-12);
  const auto mid = interpolate_pose(gt, 2.005);
  ASSERT_TRUE(mid.has_value());
  EXPECT_LT((mid->inverse() * motion(2.005)).rotation_angle(), 1e-3);
  EXPECT_FALSE(interpolate_pose(gt, -1).has_value());
  EXPECT_FALSE(interpolate_pose(gt, 10).has_value());
  Trajectory gappy = {{0, SE3()}, {1, SE3()}};
  EXPECT_FALSE(interpolate_pose(gappy, 0.5, 0.1).has_value());  // samples too far apart
}

TEST(PoseCheck, RelativePoseErrorIsZeroForTheTrueTransformAndMeasuresAPerturbation) {
  const Trajectory gt = sampled(0, 5, 100);
  const double tq = 3.0, tc = 1.0;
  const SE3 T_true = motion(tq).inverse() * motion(tc);
  const auto e0 = relative_pose_error(gt, tq, gt, tc, T_true);
  ASSERT_TRUE(e0.valid);
  EXPECT_LT(e0.rotation_deg, 1e-6);
  EXPECT_LT(e0.translation_m, 1e-9);
  const SE3 bump(Eigen::Quaterniond(Eigen::AngleAxisd(3.0 * M_PI / 180, Eigen::Vector3d::UnitZ())),
                 Eigen::Vector3d(0.04, 0, 0));
  const auto e1 = relative_pose_error(gt, tq, gt, tc, bump * T_true);
  EXPECT_NEAR(e1.rotation_deg, 3.0, 1e-6);
  EXPECT_FALSE(relative_pose_error(gt, 50, gt, tc, T_true).valid);
}

TEST(PoseCheck, TimeOffsetIsRecovered) {
  // Ground truth at 100 Hz; the estimate at 30 Hz with its clock 12 ms behind: the pose it
  // stamps t was really taken at t + 0.012.
  const Trajectory gt = sampled(0, 20, 100);
  const Trajectory est = sampled(0.5, 19, 30, 0.012);
  const auto r = estimate_time_offset(gt, est);
  ASSERT_TRUE(r.ok);
  EXPECT_NEAR(r.offset_s, 0.012, 0.0015);
  EXPECT_LT(r.median_rotation_deg, r.median_rotation_deg_at_zero);
  const auto aligned = estimate_time_offset(gt, sampled(0.5, 19, 30));
  EXPECT_NEAR(aligned.offset_s, 0.0, 0.0015);
}

TEST(PoseCheck, TimeOffsetNeedsOverlap) {
  const Trajectory gt = sampled(0, 2, 100);
  EXPECT_THROW(estimate_time_offset(gt, sampled(10, 12, 30)), InputError);
  TimeOffsetConfig bad;
  bad.step_s = 0;
  EXPECT_THROW(estimate_time_offset(gt, gt, bad), ConfigError);
}
