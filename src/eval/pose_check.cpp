#include "eval/pose_check.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace cslam {

namespace {

double median_of(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

double rotation_deg(const SE3& T) { return T.rotation_angle() * 180.0 / M_PI; }

}  // namespace

RelativePoseError relative_pose_error(const Trajectory& gt_query, double query_time, const Trajectory& gt_candidate,
                                      double candidate_time, const SE3& T_query_candidate, double offset_s) {
  RelativePoseError e;
  const auto q = interpolate_pose(gt_query, query_time + offset_s);
  const auto c = interpolate_pose(gt_candidate, candidate_time + offset_s);
  if (!q || !c) return e;
  const SE3 T_gt = q->inverse() * *c;  // T_query_world * T_world_candidate
  const SE3 D = T_gt.inverse() * T_query_candidate;
  e.valid = true;
  e.rotation_deg = rotation_deg(D);
  e.translation_m = D.translation().norm();
  return e;
}

TimeOffsetResult estimate_time_offset(const Trajectory& ground_truth, const Trajectory& estimate,
                                      const TimeOffsetConfig& config) {
  if (config.step_s <= 0 || config.search_s < 0 || config.window_s <= 0)
    throw ConfigError("time offset search: step and window must be > 0, search >= 0");
  Trajectory est = estimate;
  sort_by_time(est);
  // Pairs (i, j) of estimate poses about window_s apart.
  std::vector<std::pair<size_t, size_t>> pairs;
  for (size_t i = 0, j = 0; i < est.size(); ++i) {
    const double target = est[i].timestamp + config.window_s;
    if (j <= i) j = i + 1;
    while (j < est.size() && est[j].timestamp < target) ++j;
    if (j >= est.size()) break;
    if (est[j].timestamp - target < 0.5 * config.window_s) pairs.emplace_back(i, j);
  }
  auto median_error = [&](double offset, int& used) {
    std::vector<double> errors;
    for (const auto& [i, j] : pairs) {
      const SE3 T_est = est[i].T_world_cam.inverse() * est[j].T_world_cam;
      const auto e = relative_pose_error(ground_truth, est[i].timestamp, ground_truth, est[j].timestamp, T_est, offset);
      if (e.valid) errors.push_back(e.rotation_deg);
    }
    used = int(errors.size());
    return median_of(errors);
  };
  TimeOffsetResult r;
  int used = 0;
  r.median_rotation_deg_at_zero = median_error(0, used);
  if (used < 10)
    throw InputError("time offset", "only " + std::to_string(used) + " pose pairs " + std::to_string(config.window_s) +
                                        " s apart have ground truth (need >= 10)");
  r.median_rotation_deg = r.median_rotation_deg_at_zero;
  r.pairs = used;
  const int steps = int(std::lround(config.search_s / config.step_s));
  for (int k = -steps; k <= steps; ++k) {
    const double offset = k * config.step_s;
    int n = 0;
    const double m = median_error(offset, n);
    if (n >= 10 && m < r.median_rotation_deg) {
      r.median_rotation_deg = m;
      r.offset_s = offset;
      r.pairs = n;
    }
  }
  r.ok = true;
  return r;
}

}  // namespace cslam
