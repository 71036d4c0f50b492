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
// Largest timestamp magnitude the writers print: 1e11 s (about 3000 years of Unix time). A
// larger one is a corrupt stamp; "%.6f" of 1e300 would be a 300-digit number.
constexpr double kMaxTumTimestamp = 1e11;
// True if the stamp is finite and within +-kMaxTumTimestamp.
bool tum_stamp_ok(double timestamp);

// Writes atomically (temp file + rename). Throws InputError if the file cannot be written,
// std::invalid_argument on a non-finite pose. Poses whose stamp fails tum_stamp_ok are left out
// and counted in a comment line ("# N poses with a non-finite or out-of-range timestamp left out").
void write_tum_trajectory(const std::string& path, const Trajectory& trajectory, const std::string& header = "");
// One TUM line. A stamp that fails tum_stamp_ok is printed as "nan" (never as hundreds of
// digits); writers leave such poses out before calling it.
std::string format_tum_line(const StampedPose& pose);

// Sorts by timestamp (stable), e.g. to merge pose lists of several clients.
void sort_by_time(Trajectory& trajectory);

// Pose at time t, interpolated between the two samples around it (linear translation, slerp
// rotation); empty if t lies outside the trajectory or the samples around it are more than
// max_gap_s apart. `trajectory` sorted by time.
std::optional<SE3> interpolate_pose(const Trajectory& trajectory, double t, double max_gap_s = 0.1);

}  // namespace cslam
