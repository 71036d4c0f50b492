#pragma once
// RANSAC estimation of the similarity S_12 between two RGB-D keyframes from 3D-3D matches
// (loop closing: current keyframe vs loop candidate; map fusion: keyframes of two clients).
// Minimal samples of 3 matches are solved in closed form (Horn/Umeyama; scale fixed to 1 when
// fix_scale, which is the RGB-D case). A match is an inlier when it reprojects in BOTH images:
// S_12 * p2 projected with k1 against uv1 and S_21 * p1 projected with k2 against uv2, each with
// squared pixel error / sigma2 < chi2 (9.21 = chi2(2 dof, 99%)). The best model is re-estimated on
// all its inliers (twice, re-classifying in between). Pure maths: no logging, no map access.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "geometry/se3.h"
#include "optimize/reprojection_cost.h"

namespace cslam {

struct Sim3Correspondence {
  Eigen::Vector3d p1, p2;             // the same physical point in camera 1 and camera 2 coordinates (metres)
  Eigen::Vector2d uv1, uv2;           // its undistorted keypoints in image 1 and image 2
  double sigma2_1 = 1, sigma2_2 = 1;  // keypoint level variance (scale^2) in each image
  // Where uv1 was observed: camera-1 coordinates into the observing camera's. Identity when image 1
  // is camera 1's own; another keyframe of camera 1's map (known relative pose) when a refinement
  // pools the observations of a window of keyframes. p1 is always in camera-1 coordinates.
  SE3 T_view_1;
};

struct Sim3RansacConfig {
  int max_iterations = 300;   // hard cap on minimal samples drawn
  double probability = 0.99;  // stop early once an all-inlier sample was drawn with this probability
  int min_inliers = 20;       // success needs at least this many inliers after re-estimation
  double chi2 = 9.21;         // per-image threshold on squared reprojection error / sigma2
  bool fix_scale = true;      // RGB-D / stereo: SE3; monocular: false (7 DoF)
  std::uint64_t seed = 1;     // sampling is deterministic for a given seed
};

struct Sim3RansacResult {
  bool success = false;
  Sim3 S_12;                 // maps camera-2 coordinates into camera 1: p1 = S_12 * p2
  std::vector<char> inlier;  // per match
  int num_inliers = 0;
  int iterations = 0;  // minimal samples drawn
};

// Throws ConfigError on an impossible config (max_iterations < 1, probability outside (0,1),
// min_inliers < 3, chi2 <= 0). Fewer than 3 matches (or min_inliers) is not an error: success = false.
Sim3RansacResult sim3_ransac(const std::vector<Sim3Correspondence>& matches, const StereoIntrinsics& k1,
                             const StereoIntrinsics& k2, const Sim3RansacConfig& cfg = {});

// Squared reprojection errors / sigma2 of one match under S_12 in image 1 (e1, seen from T_view_1) and image 2 (e2);
// +infinity when the point falls behind the camera. The inlier test is e1 < chi2 && e2 < chi2.
struct Sim3MatchChi2 {
  double e1 = 0, e2 = 0;
};
Sim3MatchChi2 sim3_match_chi2(const Sim3& S_12, const Sim3Correspondence& m, const StereoIntrinsics& k1,
                              const StereoIntrinsics& k2);

}  // namespace cslam
