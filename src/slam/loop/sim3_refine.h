#pragma once
// Non-linear refinement of S_12 (from sim3_ransac) over reprojection residuals in both images
// (S_12 * p2 into image 1, S_21 * p1 into image 2, each whitened by 1/sigma):
//  stage 1: 10 iterations, Cauchy kernel (scale sqrt(chi2)) over every match: its influence
//           fades for gross errors, so many wrong matches do not bias the estimate (with a Huber
//           kernel, 50% wrong matches pull the solution several pixels off and lose inliers);
//  outlier check: a match is dropped when either image's error^2/sigma2 exceeds chi2;
//  stage 2: 10 more iterations, Huber kernel (delta = sqrt(chi2)), on the remaining matches
//           (skipped if fewer than 3);
//  final classification of every match.
// fix_scale keeps the log-scale block constant (RGB-D / stereo); otherwise 7 DoF.
// refine_sim3 solves each stage with the project's Levenberg-Marquardt (optimize/lm_driver.h: Ceres'
// step control) on analytic Jacobians (sim3_projection.h), in Ceres' parameters and cost, so it
// takes the steps refine_sim3_ceres takes (Ceres, autodiff, dense QR; the reference the tests and
// cslam-bench-loop compare against) and ends where it ends, up to rounding.
#include <vector>

#include "slam/loop/sim3_ransac.h"

namespace cslam {

struct Sim3RefineResult {
  Sim3 S_12;
  std::vector<char> inlier;  // per match, after the final classification
  int num_inliers = 0;
  // Huber cost (delta = sqrt(chi2)) of the final inliers at the initial and at the refined S_12.
  double initial_cost = 0, final_cost = 0;
  bool converged = false;  // the last solver stage converged (Ceres' CONVERGENCE, not just max iterations)
};

// Throws ConfigError if chi2 <= 0. Fewer than 3 matches: returns the initial S_12, no inliers.
Sim3RefineResult refine_sim3(const Sim3& S_12_initial, const std::vector<Sim3Correspondence>& matches,
                             const StereoIntrinsics& k1, const StereoIntrinsics& k2, bool fix_scale,
                             double chi2 = 10.0);
Sim3RefineResult refine_sim3_ceres(const Sim3& S_12_initial, const std::vector<Sim3Correspondence>& matches,
                                   const StereoIntrinsics& k1, const StereoIntrinsics& k2, bool fix_scale,
                                   double chi2 = 10.0);

// Flags the matches whose squared reprojection error over sigma2 is at most chi2 in both images;
// returns their number.
int classify_sim3_matches(const Sim3& S_12, const std::vector<Sim3Correspondence>& matches, const StereoIntrinsics& k1,
                          const StereoIntrinsics& k2, double chi2, std::vector<char>& inlier);

}  // namespace cslam
