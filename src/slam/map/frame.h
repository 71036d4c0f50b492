#pragma once
// A frame being tracked: the shared immutable FrameData plus the tracker's per-frame state.
#include <memory>
#include <vector>

#include "slam/map/keyframe.h"

namespace cslam {

struct Frame {
  explicit Frame(std::shared_ptr<const FrameData> d)
      : data(std::move(d)), map_points(data->size()), outlier(data->size(), 0) {}

  std::shared_ptr<const FrameData> data;
  SE3 T_cam_world;
  bool has_pose = false;
  std::vector<MapPointPtr> map_points;  // matched map point per keypoint (may be temporal)
  std::vector<char> outlier;
  KeyFramePtr reference;
  SE3 T_cam_ref;  // pose relative to the reference keyframe, fixed when tracked
  // Visual-odometry points created for the previous frame only (not in the map).
  std::vector<MapPointPtr> temporal_points;

  Eigen::Vector3d center() const { return T_cam_world.inverse().translation(); }
  int num_matches() const {
    int n = 0;
    for (size_t i = 0; i < map_points.size(); ++i)
      if (map_points[i] && !outlier[i]) ++n;
    return n;
  }
};

}  // namespace cslam
