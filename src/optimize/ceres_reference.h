#pragma once
// Reference implementations on Ceres with autodiff, kept as the ground truth that the fast
// optimisers are checked against (tests/optimize) and timed against (cslam-bench-optimize).
// Same inputs, outputs and outlier scheme as optimize_pose / bundle_adjust; not used by the
// SLAM pipeline.
#include <atomic>
#include <vector>

#include "optimize/bundle_adjustment.h"
#include "optimize/pose_optimizer.h"

namespace cslam {

// Pose-only optimisation, one Ceres problem (DENSE_QR, autodiff) per round.
PoseOptimizationResult optimize_pose_ceres(const SE3& T_cam_world_initial,
                                           const std::vector<PoseObservation>& observations,
                                           const StereoIntrinsics& intrinsics,
                                           const PoseOptimizationConfig& config = {});

// Bundle adjustment with autodiff residuals, SPARSE_SCHUR and Ceres' own elimination ordering.
BaResult bundle_adjust_ceres(const BaProblem& problem, const BaConfig& config = {},
                             const std::atomic<bool>* abort = nullptr);

}  // namespace cslam
