#pragma once
// Checks of measured relative poses (loop and fusion transforms) against ground truth, and the
// estimate of a constant time offset between a sequence's camera clock and its ground-truth clock.
// Ground truth is interpolated (linear translation, slerp rotation), not taken at the nearest
// sample: fr1 sequences rotate at up to ~100 deg/s, so 5 ms of sampling is already 0.5 deg.
#include <optional>
#include <vector>

#include "io/trajectory_io.h"

namespace cslam {

struct RelativePoseError {
  bool valid = false;  // both timestamps had ground truth
  double rotation_deg = 0, translation_m = 0;
};
// Error of a measured camera-to-camera transform (p_query = T * p_candidate) against ground truth
// at (query_time + offset, candidate_time + offset). The two cameras may come from different
// ground-truth files in one world frame (robots of one synthetic scene).
RelativePoseError relative_pose_error(const Trajectory& gt_query, double query_time, const Trajectory& gt_candidate,
                                      double candidate_time, const SE3& T_query_candidate, double offset_s = 0);

struct TimeOffsetConfig {
  double search_s = 0.05;  // offsets tried in [-search, +search]
  double step_s = 0.001;
  double window_s = 0.5;  // pose pairs this far apart are compared
};
struct TimeOffsetResult {
  bool ok = false;
  double offset_s = 0;             // add to the estimate's timestamps to read ground truth
  double median_rotation_deg = 0;  // relative-rotation error at the best offset
  double median_rotation_deg_at_zero = 0;
  int pairs = 0;
};
// The constant offset minimising the median relative-rotation error of pose pairs window_s apart
// (rotation only: it is independent of any alignment and of drift in translation). Throws
// InputError if fewer than 10 pairs can be compared.
TimeOffsetResult estimate_time_offset(const Trajectory& ground_truth, const Trajectory& estimate,
                                      const TimeOffsetConfig& config = {});

}  // namespace cslam
