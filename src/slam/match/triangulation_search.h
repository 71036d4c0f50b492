#pragma once
// Matching for triangulation (ORB-SLAM2's SearchForTriangulation): pairs of keypoints of two
// keyframes that have no map point yet, under the same vocabulary node, close in descriptor
// space and consistent with the epipolar geometry of the two keyframe poses.
// Reads keyframe data and map-point slots: the caller holds the map mutex (shared).
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "slam/map/keyframe.h"

namespace cslam {

// Fundamental matrix F_21 with x2^T F_21 x1 = 0 for pixel coordinates (u, v, 1) of the undistorted
// keypoints of camera 1 and camera 2; the epipolar line of x1 in image 2 is F_21 x1.
Eigen::Matrix3d fundamental_21(const SE3& T_cam1_world, const PinholeCamera& cam1, const SE3& T_cam2_world,
                               const PinholeCamera& cam2);

struct TriangulationSearchParams {
  int max_distance = 50;          // Hamming distance (ORB-SLAM2's TH_LOW)
  double epipolar_chi2 = 3.84;    // squared distance to the epipolar line, in level sigmas^2 (1 dof, 95 %)
  double epipole_radius = 100.0;  // pixels (x level scale): monocular pairs near the epipole are ambiguous
  bool check_orientation = true;
};

// Index pairs (keypoint of kf1, keypoint of kf2), each keypoint used once, sorted by kf1 index.
// skip1: if non-null, keypoints i of kf1 with (*skip1)[i] != 0 are left out.
std::vector<std::pair<int, int>> search_for_triangulation(const KeyFrame& kf1, const KeyFrame& kf2,
                                                          const TriangulationSearchParams& params = {},
                                                          const std::vector<char>* skip1 = nullptr);

}  // namespace cslam
