#include "optimize/sparse_ba.h"

#include <array>
#include <cmath>
#include <memory>

#include <ceres/ceres.h>

#include "optimize/ceres_ba_common.h"

#include "optimize/pose_param.h"
#include "optimize/se3_projection.h"

namespace cslam {

namespace {

// Rotation, right Jacobian and translation of every camera at the point being evaluated.
class CameraCache : public ceres::EvaluationCallback {
 public:
  explicit CameraCache(std::vector<std::array<double, 6>>& poses) : poses_(poses), points_(poses.size()) {
    for (size_t c = 0; c < poses_.size(); ++c) points_[c].set(poses_[c].data());
  }
  void PrepareForEvaluation(bool, bool new_evaluation_point) override {
    if (!new_evaluation_point) return;
    for (size_t c = 0; c < poses_.size(); ++c) points_[c].set(poses_[c].data());
  }
  const PoseLinearizationPoint& operator[](int c) const { return points_[c]; }

 private:
  std::vector<std::array<double, 6>>& poses_;
  std::vector<PoseLinearizationPoint> points_;
};

template <int kResiduals>
class AnalyticReprojectionCost : public ceres::SizedCostFunction<kResiduals, 6, 3> {
 public:
  AnalyticReprojectionCost(const CameraCache& cache, int camera, const StereoIntrinsics& k, const BaObservation& o)
      : cache_(cache), camera_(camera), k_(k), obs_(o.uv.x(), o.uv.y(), o.u_right), w_(std::sqrt(o.inv_sigma2)) {}

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const Eigen::Vector3d pw(parameters[1][0], parameters[1][1], parameters[1][2]);
    Eigen::Vector3d uvr;
    Matrix36d Jc;
    Eigen::Matrix3d Jp;
    project_with_jacobians(k_, cache_[camera_], pw, uvr, Jc, Jp);
    for (int r = 0; r < kResiduals; ++r) residuals[r] = w_ * (uvr(r) - obs_(r));
    if (!jacobians) return true;
    if (jacobians[0]) {
      Eigen::Map<Eigen::Matrix<double, kResiduals, 6, Eigen::RowMajor>> J(jacobians[0]);
      J = w_ * Jc.topRows<kResiduals>();
    }
    if (jacobians[1]) {
      Eigen::Map<Eigen::Matrix<double, kResiduals, 3, Eigen::RowMajor>> J(jacobians[1]);
      J = w_ * Jp.topRows<kResiduals>();
    }
    return true;
  }

 private:
  const CameraCache& cache_;
  const int camera_;
  const StereoIntrinsics k_;
  const Eigen::Vector3d obs_;
  const double w_;
};

ceres::LinearSolverType to_ceres(SparseBaLinearSolver s) {
  switch (s) {
    case SparseBaLinearSolver::kDenseSchur:
      return ceres::DENSE_SCHUR;
    case SparseBaLinearSolver::kIterativeSchur:
      return ceres::ITERATIVE_SCHUR;
    case SparseBaLinearSolver::kSparseSchur:
      break;
  }
  return ceres::SPARSE_SCHUR;
}

}  // namespace

BaResult bundle_adjust_sparse(const BaProblem& prob, const BaConfig& cfg, const std::atomic<bool>* abort,
                              SparseBaLinearSolver solver) {
  BaResult res;
  std::vector<std::array<double, 6>> poses;
  poses.reserve(prob.cameras.size());
  for (const auto& c : prob.cameras) poses.push_back(to_param(c.T_cam_world));
  std::vector<std::array<double, 3>> pts;
  pts.reserve(prob.points.size());
  for (const auto& p : prob.points) pts.push_back({p.x(), p.y(), p.z()});
  res.inlier.assign(prob.observations.size(), 1);

  CameraCache cache(poses);
  // Shared kernels; the problem does not own them (they are switched off for the second stage).
  ceres::LossFunctionWrapper loss_mono(new ceres::HuberLoss(std::sqrt(cfg.chi2_mono)), ceres::TAKE_OWNERSHIP);
  ceres::LossFunctionWrapper loss_stereo(new ceres::HuberLoss(std::sqrt(cfg.chi2_stereo)), ceres::TAKE_OWNERSHIP);
  ceres::Problem::Options popts;
  popts.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  popts.evaluation_callback = &cache;
  popts.enable_fast_removal = true;
  ceres::Problem problem(popts);
  std::vector<ceres::ResidualBlockId> blocks(prob.observations.size(), nullptr);
  std::vector<int> point_residuals(prob.points.size(), 0);
  for (size_t i = 0; i < prob.observations.size(); ++i) {
    const auto& o = prob.observations[i];
    const auto& k = prob.cameras[o.camera].intrinsics;
    const bool stereo = o.u_right >= 0;
    ceres::CostFunction* cost =
        stereo ? static_cast<ceres::CostFunction*>(new AnalyticReprojectionCost<3>(cache, o.camera, k, o))
               : new AnalyticReprojectionCost<2>(cache, o.camera, k, o);
    blocks[i] =
        problem.AddResidualBlock(cost, stereo ? &loss_stereo : &loss_mono, poses[o.camera].data(), pts[o.point].data());
    ++point_residuals[o.point];
  }
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (size_t p = 0; p < pts.size(); ++p)
    if (point_residuals[p] > 0) ordering->AddElementToGroup(pts[p].data(), 0);
  for (size_t c = 0; c < poses.size(); ++c) {
    if (!problem.HasParameterBlock(poses[c].data())) continue;
    if (prob.cameras[c].fixed) problem.SetParameterBlockConstant(poses[c].data());
    ordering->AddElementToGroup(poses[c].data(), 1);
  }

  ceres_ba::AbortCallback callback(abort, cfg.keep_progress_on_abort);
  auto run_stage = [&](int iterations) {
    if (problem.NumResidualBlocks() == 0) return;
    ceres::Solver::Options opts;
    opts.linear_solver_type = to_ceres(solver);
    opts.preconditioner_type = ceres::SCHUR_JACOBI;
    opts.linear_solver_ordering = ordering;
    opts.max_num_iterations = iterations;
    opts.num_threads = cfg.threads;
    opts.logging_type = ceres::SILENT;
    if (abort) opts.callbacks.push_back(&callback);
    ceres::Solver::Summary summary;
    ceres::Solve(opts, &problem, &summary);
    ceres_ba::accumulate(summary, res);
  };
  auto classify = [&] {
    std::vector<BaCamera> cams = prob.cameras;
    for (size_t c = 0; c < cams.size(); ++c) cams[c].T_cam_world = from_param(poses[c].data());
    for (size_t i = 0; i < prob.observations.size(); ++i) {
      const auto& o = prob.observations[i];
      const Eigen::Vector3d p(pts[o.point][0], pts[o.point][1], pts[o.point][2]);
      res.inlier[i] = ba_observation_chi2(cams[o.camera], p, o) <= (o.u_right >= 0 ? cfg.chi2_stereo : cfg.chi2_mono);
    }
  };

  run_stage(cfg.first_iterations);
  if (!res.aborted && cfg.second_iterations > 0) {
    classify();
    // Second stage: the inliers only, without kernel. Points and keyframes left without
    // residuals leave the problem (the reference does not add them).
    loss_mono.Reset(nullptr, ceres::TAKE_OWNERSHIP);
    loss_stereo.Reset(nullptr, ceres::TAKE_OWNERSHIP);
    std::vector<int> camera_residuals(poses.size(), 0);
    for (size_t i = 0; i < prob.observations.size(); ++i) {
      const auto& o = prob.observations[i];
      if (res.inlier[i]) {
        ++camera_residuals[o.camera];
        continue;
      }
      problem.RemoveResidualBlock(blocks[i]);
      if (--point_residuals[o.point] == 0) {
        ordering->Remove(pts[o.point].data());
        problem.RemoveParameterBlock(pts[o.point].data());
      }
    }
    for (size_t c = 0; c < poses.size(); ++c)
      if (problem.HasParameterBlock(poses[c].data()) && camera_residuals[c] == 0) {
        ordering->Remove(poses[c].data());
        problem.RemoveParameterBlock(poses[c].data());
      }
    run_stage(cfg.second_iterations);
  }
  classify();
  for (const auto& p : poses) res.T_cam_world.push_back(from_param(p.data()));
  for (const auto& p : pts) res.points.emplace_back(p[0], p[1], p[2]);
  return res;
}

}  // namespace cslam
