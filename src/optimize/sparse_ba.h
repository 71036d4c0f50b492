#pragma once
// Bundle adjustment on Ceres' sparse Schur solver, a second reference for the block-sparse path
// of schur_ba.h (global and group BAs): analytic Jacobians, the per-camera rotation and its
// derivative computed once per evaluation point (an EvaluationCallback), two shared Huber kernels
// that are switched off for the second stage, the problem built once (the second stage only
// removes the outliers), and the point/keyframe elimination ordering given explicitly. Same cost,
// parameters and outlier scheme as bundle_adjust_ceres.
#include <atomic>

#include "optimize/bundle_adjustment.h"

namespace cslam {

enum class SparseBaLinearSolver { kSparseSchur, kDenseSchur, kIterativeSchur };

BaResult bundle_adjust_sparse(const BaProblem& problem, const BaConfig& config = {},
                              const std::atomic<bool>* abort = nullptr,
                              SparseBaLinearSolver solver = SparseBaLinearSolver::kSparseSchur);

}  // namespace cslam
