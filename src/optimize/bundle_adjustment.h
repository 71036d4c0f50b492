#pragma once
// Bundle adjustment of keyframe poses and points over reprojection (RGB-D "stereo") residuals,
// used for local BA (covisible keyframes free, the second ring fixed) and global BA.
// An own Schur-complement Levenberg-Marquardt (schur_ba.h) with a dense reduced camera system up
// to 96 free keyframes and a block-sparse one beyond; it takes the steps of the Ceres reference
// (bundle_adjust_ceres in ceres_reference.h). sparse_ba.h keeps the same problem on Ceres'
// SPARSE_SCHUR as a second reference for large problems; see docs/performance.md.
#include <atomic>
#include <vector>

#include "geometry/se3.h"
#include "optimize/reprojection_cost.h"

namespace cslam {

struct BaCamera {
  SE3 T_cam_world;
  StereoIntrinsics intrinsics;
  bool fixed = false;
};

struct BaObservation {
  int camera = 0, point = 0;
  Eigen::Vector2d uv;
  double u_right = -1;
  double inv_sigma2 = 1;
};

struct BaProblem {
  std::vector<BaCamera> cameras;
  std::vector<Eigen::Vector3d> points;
  std::vector<BaObservation> observations;
};

struct BaConfig {
  int first_iterations = 5;    // with the Huber kernel
  int second_iterations = 10;  // after dropping outliers, no kernel (0: single stage)
  double chi2_mono = 5.991, chi2_stereo = 7.815;
  // A stage ends after an accepted step that lowered its cost by at most this fraction (lm_driver.h;
  // 0: Ceres' termination rules alone). Not in the Ceres paths.
  double min_step_decrease = 1e-4;
  int threads = 1;  // Ceres threads of bundle_adjust_sparse (bundle_adjust is single-threaded)
  // An aborted solve returns its last accepted iterate (BaResult::partial) instead of the values
  // it started from: every accepted step lowered the cost, so a cut-short solve is still progress.
  bool keep_progress_on_abort = false;
};

struct BaResult {
  std::vector<SE3> T_cam_world;         // per camera
  std::vector<Eigen::Vector3d> points;  // per point
  std::vector<char> inlier;             // per observation
  double initial_cost = 0, final_cost = 0;
  int iterations = 0;
  bool converged = false, aborted = false;
  bool partial = false;  // aborted with keep_progress_on_abort: the result is the last accepted iterate
};

// `abort` (optional) stops the solver between iterations when set (e.g. a new keyframe arrived);
// the result is then the start, or with keep_progress_on_abort the last accepted iterate.
BaResult bundle_adjust(const BaProblem& problem, const BaConfig& config = {}, const std::atomic<bool>* abort = nullptr);

// Whitened squared reprojection error of one observation (infinite behind the camera).
double ba_observation_chi2(const BaCamera& cam, const Eigen::Vector3d& p, const BaObservation& o);

}  // namespace cslam
