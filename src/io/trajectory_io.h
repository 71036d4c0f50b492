#pragma once
// Trajectories in the TUM format: one line per pose, "timestamp x y z qx qy qz qw",
// camera-to-world (T_world_cam), '#' comments allowed.
#include <optional>
#include <string>
#include <vector>

#include "geometry/se3.h"

namespace cslam {

struct StampedPose {
  double timestamp = 0;
  SE3 T_world_cam;
};
using Trajectory = std::vector<StampedPose>;

// Throws InputError naming file and line on a malformed line, a non-finite value or a
// zero quaternion. Quaternions are normalised.
Trajectory read_tum_trajectory(const std::string& path);
// Writes atomically (temp file + rename). Throws InputError if the file cannot be written,
// std::invalid_argument on a non-finite pose.
void write_tum_trajectory(const std::string& path, const Trajectory& trajectory, const std::string& header = "");
std::string format_tum_line(const StampedPose& pose);

// Sorts by timestamp (stable), e.g. to merge pose lists of several clients.
void sort_by_time(Trajectory& trajectory);

// Pose at time t, interpolated between the two samples around it (linear translation, slerp
// rotation); empty if t lies outside the trajectory or the samples around it are more than
// max_gap_s apart. `trajectory` sorted by time.
std::optional<SE3> interpolate_pose(const Trajectory& trajectory, double t, double max_gap_s = 0.1);

}  // namespace cslam
