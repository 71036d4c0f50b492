#pragma once
// Verification of a place-recognition candidate between two keyframes (of the same or of two
// different maps): BoW matches of their map points, RANSAC SE3/Sim3 on the 3D-3D matches with a
// reprojection inlier test in both images, Ceres refinement, then a projection check of the
// candidate's covisible keyframes' points into the query keyframe; once accepted, the transform is
// refined over the query's covisible keyframes too (window refinement). The caller holds both maps'
// mutexes (shared).
#include <string>
#include <vector>

#include "slam/loop/sim3_ransac.h"
#include "slam/map/keyframe.h"

namespace cslam {

struct OverlapVerifyConfig {
  int min_bow_matches = 20;
  Sim3RansacConfig ransac;  // fix_scale: RGB-D observes scale
  int min_refined_inliers = 20;
  int min_projection_matches = 40;  // total matches confirmed by projection
  double projection_radius = 7.5;   // pixels at level 0
  int min_final_inliers = 50;       // after refining on BoW inliers + projection matches
  // Window refinement of an accepted transform: the candidate group's points are also matched by
  // projection in the query's best covisible keyframes (their poses relative to the query are known
  // in the query's map), and one transform is fitted to every observation. One image's errors
  // (motion blur, rolling shutter, depth taken at another instant) then average out. 0 disables it.
  int window_keyframes = 10;
};

struct OverlapVerifyResult {
  bool accepted = false;
  std::string reason;      // why it was rejected
  Sim3 S_query_candidate;  // maps candidate-camera coordinates into query-camera coordinates
  int bow_matches = 0, ransac_inliers = 0, refined_inliers = 0, projection_matches = 0, final_inliers = 0;
  int window_keyframes = 0;  // query-map keyframes whose observations the window fit used (query included)
  int window_inliers = 0;    // inliers of the window fit (0: no window fit)
};

OverlapVerifyResult verify_overlap(const KeyFrame& query, const KeyFrame& candidate,
                                   const std::vector<KeyFrame*>& candidate_neighbours,
                                   const OverlapVerifyConfig& config);

}  // namespace cslam
