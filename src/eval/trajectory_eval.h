#pragma once
// Absolute and relative trajectory error against ground truth (as evo's APE/RPE, translation in m).
#include <string>
#include <utility>
#include <vector>

#include "core/stats.h"
#include "geometry/alignment.h"  // umeyama(), UmeyamaResult (moved to geometry, still exported here)
#include "geometry/se3.h"
#include "io/trajectory_io.h"

namespace cslam {

enum class Alignment { kNone, kSE3, kSim3 };
Alignment parse_alignment(const std::string& text);  // "none" | "se3" | "sim3"; throws ConfigError

// Index pairs (gt, est) associated by nearest timestamp within max_dt, each pose used once.
std::vector<std::pair<int, int>> associate_trajectories(const Trajectory& gt, const Trajectory& est, double max_dt);

struct AteResult {
  ErrorStats stats;
  Sim3 T_gt_est;                   // alignment applied to the estimate
  std::vector<double> timestamps;  // estimate's timestamps of associated poses
  std::vector<double> errors;      // per associated pose, metres
};
// Throws InputError (source "ATE") if fewer than 3 poses associate.
AteResult compute_ate(const Trajectory& gt, const Trajectory& est, Alignment align, double max_dt = 0.02);

// Joint ATE of several (ground truth, estimate) pairs with ONE alignment: each pair is associated
// on its own (clients may share timestamps), then all positions are aligned together. This is the
// accuracy of a fused group's combined trajectory.
AteResult compute_ate_joint(const std::vector<std::pair<Trajectory, Trajectory>>& pairs, Alignment align,
                            double max_dt = 0.02);

struct RpeResult {
  ErrorStats translation;  // metres
  ErrorStats rotation;     // degrees
};
// Pairs (i, j) of estimate poses with t_j - t_i closest to delta_s (within max_dt); errors of the
// relative motion against ground truth. Throws InputError if no pair is found.
RpeResult compute_rpe(const Trajectory& gt, const Trajectory& est, double delta_s, double max_dt = 0.02);

}  // namespace cslam
