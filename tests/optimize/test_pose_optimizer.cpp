#include <gtest/gtest.h>

#include "support/problems/optimize_problems.h"
#include "optimize/pose_optimizer.h"

using namespace cslam;

TEST(PoseOptimizer, RecoversPerturbedPoseWithOutliers) {
  std::mt19937 rng(7);
  const auto k = problems::tum_like_intrinsics();
  const SE3 truth = problems::small_motion(0.2, {0.1, 1, 0.2}, {0.05, -0.1, 0.2});
  const auto pts = problems::random_points_in_front(300, rng);
  std::normal_distribution<double> noise(0, 0.5);
  std::uniform_real_distribution<double> wild(0, 640);
  std::vector<PoseObservation> obs;
  std::vector<char> is_outlier;
  for (size_t i = 0; i < pts.size(); ++i) {
    // Points are given in the world frame: map them so they are in front of the true camera.
    const Eigen::Vector3d pw = truth.inverse() * pts[i];
    Eigen::Vector3d uvr = problems::project(k, truth, pw);
    const bool outlier = i % 5 == 0;  // 20% gross outliers
    if (outlier)
      uvr = {wild(rng), wild(rng) * 0.75, -1};
    else
      uvr += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    PoseObservation o;
    o.p_world = pw;
    o.uv = uvr.head<2>();
    o.u_right = (i % 2 == 0 || outlier) ? -1 : uvr.z();  // mix of mono and stereo observations
    obs.push_back(o);
    is_outlier.push_back(outlier);
  }
  const SE3 start = problems::small_motion(0.05, {1, 0, 0}, Eigen::Vector3d(0.03, 0.02, -0.04)) * truth;
  const auto r = optimize_pose(start, obs, k);
  EXPECT_LT(r.T_cam_world.rotation().angularDistance(truth.rotation()), 0.2 * M_PI / 180);
  EXPECT_LT((r.T_cam_world.translation() - truth.translation()).norm(), 0.005);
  int flagged = 0, wrong = 0;
  for (size_t i = 0; i < obs.size(); ++i) {
    if (is_outlier[i] && !r.inlier[i]) ++flagged;
    if (!is_outlier[i] && !r.inlier[i]) ++wrong;
  }
  EXPECT_EQ(flagged, 60);  // every gross outlier rejected
  EXPECT_LT(wrong, 10);    // few good observations lost
  EXPECT_GE(r.num_inliers, 230);
}

TEST(PoseOptimizer, TooFewObservations) {
  const auto r = optimize_pose(SE3(), {}, problems::tum_like_intrinsics());
  EXPECT_EQ(r.num_inliers, 0);
}
