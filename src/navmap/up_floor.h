#pragma once
// The up direction and the floor height of a SLAM world that has no gravity: its frame is the
// first camera's frame, so both are estimated from the cameras and the dense map.
#include <string>
#include <vector>

#include "geometry/se3.h"
#include "navmap/nav_config.h"
#include "navmap/submap_view.h"

namespace cslam {

struct UpEstimate {
  Eigen::Vector3d up{0, 0, 1};  // unit vector, world frame
  bool from_cameras = false;    // false: the default was used
  std::size_t cameras_used = 0;
  std::size_t cameras_skipped = 0;  // non-finite poses
};

// Robots carry their cameras roughly level (camera y axis pointing down, as OpenCV/TUM): up is
// minus the mean of the cameras' y axes, normalised. Falls back to default_up (normalised) when
// there is no finite pose or the y axes disagree so much that their mean is shorter than 0.5
// (cameras not level). Throws ConfigError if default_up is zero or not finite.
UpEstimate estimate_up(const std::vector<SE3>& T_world_cams, const Eigen::Vector3d& default_up);

struct FloorEstimate {
  double height = 0;        // along up, world frame (metres)
  bool found = false;       // false: no observed surface at all (height meaningless)
  std::string rule;         // "peak", "percentile" or "none"
  std::size_t samples = 0;  // upward-facing surface samples (peak rule) or surface voxels
  std::size_t peak_samples = 0;
};

// The floor's height along up (unit). Rule ("peak"): the heights of all upward-facing surface
// points (zero crossings, for_each_upward_crossing) below the cameras' median height (when
// cameras are given), sorted; the floor is the lowest cluster, a window of 3 * floor_bin that
// holds at least floor_min_share of the samples (so a few outliers below the floor are passed
// over), refined to the densest such window starting within the next window and taken as the
// median of its samples. When no window qualifies ("percentile"): the floor_percentile of the
// heights of all surface voxels (signed distance <= 0). Skips unusable views.
FloorEstimate estimate_floor(const SubmapViews& views, const Eigen::Vector3d& up, const NavMapConfig& config,
                             const std::vector<SE3>& T_world_cams = {});

// The floor rule over given sample heights (exposed for tests); nullopt if no window qualifies.
std::optional<double> floor_from_heights(std::vector<double> heights, double bin, double min_share,
                                         std::size_t* peak_samples = nullptr);

}  // namespace cslam
