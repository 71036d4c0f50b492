#pragma once
// Pose-only optimisation of one camera against known 3D points, with a Huber kernel and
// several rounds of outlier rejection (ORB-SLAM2's scheme: 4 rounds of 10 iterations,
// chi2 thresholds 5.991 (2 dof) / 7.815 (3 dof), kernel dropped in the last rounds).
// A fixed-size Levenberg-Marquardt with analytic Jacobians that takes the steps of the Ceres
// reference (optimize_pose_ceres in ceres_reference.h); no per-call solver setup.
#include <vector>

#include "geometry/se3.h"
#include "optimize/reprojection_cost.h"

namespace cslam {

struct PoseObservation {
  Eigen::Vector3d p_world;
  Eigen::Vector2d uv;     // undistorted keypoint
  double u_right = -1;    // < 0: monocular observation
  double inv_sigma2 = 1;  // of the keypoint's level
};

struct PoseOptimizationConfig {
  int rounds = 4;
  int iterations_per_round = 10;
  double chi2_mono = 5.991, chi2_stereo = 7.815;
  int robust_rounds = 2;  // rounds with the Huber kernel
  // A round ends after an accepted step that lowered its cost by at most this fraction
  // (lm_driver.h; 0: Ceres' termination rules alone).
  double min_step_decrease = 1e-4;
};

struct PoseOptimizationResult {
  SE3 T_cam_world;
  std::vector<char> inlier;
  int num_inliers = 0;
  double final_cost = 0;
  bool converged = false;
};

PoseOptimizationResult optimize_pose(const SE3& T_cam_world_initial, const std::vector<PoseObservation>& observations,
                                     const StereoIntrinsics& intrinsics, const PoseOptimizationConfig& config = {});

// chi2 of one observation at a pose (whitened squared residual).
double observation_chi2(const SE3& T_cam_world, const PoseObservation& obs, const StereoIntrinsics& k);

}  // namespace cslam
