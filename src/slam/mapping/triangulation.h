#pragma once
// New map points from pairs of keyframes (ORB-SLAM2's CreateNewMapPoints): keypoints of a new
// keyframe without a map point (no depth, depth rejected at an occlusion boundary, or far) are
// matched to those of its covisible neighbours along epipolar lines and triangulated, or
// back-projected with the depth of whichever view measures it with more parallax. A point is
// kept only if it lies in front of both cameras, reprojects within the chi-square bounds of
// its pyramid level (with the virtual right coordinate where there is depth), and its distance
// ratio between the views agrees with their pyramid levels.
#include <optional>
#include <vector>

#include "slam/map/map.h"

namespace cslam {

struct TriangulationConfig {
  bool enabled = true;
  int neighbours = 10;               // best covisible keyframes tried
  double max_parallax_cos = 0.9998;  // rays closer than ~1.1 degrees give no monocular depth
  double mono_chi2 = 5.991;          // reprojection bound, 2 dof, 95 % (x level sigma^2)
  double stereo_chi2 = 7.8;          // with the virtual right coordinate, 3 dof, 95 %
  double scale_consistency = 1.5;    // x pyramid scale factor: slack on the distance/level ratio
};

// The world point seen by keypoint i1 of view 1 and i2 of view 2, or nothing if the pair fails a
// check. Pure geometry on the two views' data and poses.
std::optional<Eigen::Vector3d> triangulate_pair(const FrameData& f1, const SE3& T_cam1_world, int i1,
                                                const FrameData& f2, const SE3& T_cam2_world, int i2,
                                                const TriangulationConfig& config);

// Creates the new points of `kf` with its neighbours; returns them (for recent-point culling).
// Requires the unique map lock.
std::vector<MapPointPtr> create_new_map_points(Map& map, KeyFrame* kf, const TriangulationConfig& config);

}  // namespace cslam
