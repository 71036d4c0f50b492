#pragma once
// Levenberg-Marquardt bundle adjustment with the points eliminated by a Schur complement. The
// reduced camera system is dense (Cholesky) up to kMaxDenseSchurCameras free keyframes (local BA)
// and block-sparse beyond (block_sparse_system.h: global and group BAs). Fixed-size Eigen blocks
// and analytic Jacobians; buffers and the sparse pattern are set up once per stage and reused by
// every iteration. Same cost, parameters and step control as the Ceres reference
// (bundle_adjust_ceres), see lm_driver.h.
#include <array>
#include <atomic>
#include <vector>

#include "optimize/bundle_adjustment.h"
#include "optimize/lm_driver.h"

namespace cslam {

// Free cameras the dense reduced camera system is used for; larger problems get the block-sparse
// one.
constexpr int kMaxDenseSchurCameras = 96;

// One stage: minimises over the observations with active[i] != 0 (Huber kernel if robust),
// updating poses (T_cam_world as [angle-axis, t], fixed cameras untouched) and points in place.
LmOutcome schur_ba_stage(const BaProblem& problem, const std::vector<char>& active, bool robust, const BaConfig& config,
                         int max_iterations, const std::atomic<bool>* abort, std::vector<std::array<double, 6>>& poses,
                         std::vector<Eigen::Vector3d>& points);

}  // namespace cslam
