#include "optimize/ceres_reference.h"

#include <cmath>

#include <ceres/ceres.h>

#include "optimize/ceres_ba_common.h"

#include "optimize/pose_param.h"

namespace cslam {

namespace {

ceres::CostFunction* make_cost(const BaCamera& cam, const BaObservation& o) {
  const double w = std::sqrt(o.inv_sigma2);
  if (o.u_right >= 0)
    return new ceres::AutoDiffCostFunction<ReprojectionCost<3>, 3, 6, 3>(
        new ReprojectionCost<3>(cam.intrinsics, o.uv.x(), o.uv.y(), o.u_right, w));
  return new ceres::AutoDiffCostFunction<ReprojectionCost<2>, 2, 6, 3>(
      new ReprojectionCost<2>(cam.intrinsics, o.uv.x(), o.uv.y(), -1, w));
}

}  // namespace

PoseOptimizationResult optimize_pose_ceres(const SE3& initial, const std::vector<PoseObservation>& obs,
                                           const StereoIntrinsics& k, const PoseOptimizationConfig& cfg) {
  PoseOptimizationResult res;
  res.T_cam_world = initial;
  res.inlier.assign(obs.size(), 1);
  if (obs.size() < 3) {
    res.num_inliers = 0;
    return res;
  }
  std::array<double, 6> param = to_param(initial);
  for (int round = 0; round < cfg.rounds; ++round) {
    ceres::Problem::Options popts;
    popts.loss_function_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem problem(popts);
    int used = 0;
    for (size_t i = 0; i < obs.size(); ++i) {
      if (!res.inlier[i]) continue;
      const auto& o = obs[i];
      const double w = std::sqrt(o.inv_sigma2);
      const bool stereo = o.u_right >= 0;
      ceres::LossFunction* loss = round < cfg.robust_rounds
                                      ? new ceres::HuberLoss(std::sqrt(stereo ? cfg.chi2_stereo : cfg.chi2_mono))
                                      : nullptr;
      ceres::CostFunction* cost =
          stereo ? static_cast<ceres::CostFunction*>(new ceres::AutoDiffCostFunction<PoseOnlyReprojectionCost<3>, 3, 6>(
                       new PoseOnlyReprojectionCost<3>(k, o.p_world, o.uv.x(), o.uv.y(), o.u_right, w)))
                 : new ceres::AutoDiffCostFunction<PoseOnlyReprojectionCost<2>, 2, 6>(
                       new PoseOnlyReprojectionCost<2>(k, o.p_world, o.uv.x(), o.uv.y(), -1, w));
      problem.AddResidualBlock(cost, loss, param.data());
      ++used;
    }
    if (used < 3) break;
    ceres::Solver::Options opts;
    opts.linear_solver_type = ceres::DENSE_QR;
    opts.max_num_iterations = cfg.iterations_per_round;
    opts.num_threads = 1;
    opts.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(opts, &problem, &summary);
    res.final_cost = summary.final_cost;
    res.converged = summary.termination_type == ceres::CONVERGENCE;
    const SE3 T = from_param(param.data());
    // Re-classify every observation (outliers may come back) against the new pose.
    for (size_t i = 0; i < obs.size(); ++i) {
      const double chi2 = observation_chi2(T, obs[i], k);
      res.inlier[i] = chi2 <= (obs[i].u_right >= 0 ? cfg.chi2_stereo : cfg.chi2_mono);
    }
  }
  res.T_cam_world = from_param(param.data());
  res.num_inliers = 0;
  for (char c : res.inlier) res.num_inliers += c ? 1 : 0;
  return res;
}

BaResult bundle_adjust_ceres(const BaProblem& prob, const BaConfig& cfg, const std::atomic<bool>* abort) {
  BaResult res;
  std::vector<std::array<double, 6>> poses;
  poses.reserve(prob.cameras.size());
  for (const auto& c : prob.cameras) poses.push_back(to_param(c.T_cam_world));
  std::vector<std::array<double, 3>> pts;
  pts.reserve(prob.points.size());
  for (const auto& p : prob.points) pts.push_back({p.x(), p.y(), p.z()});
  res.inlier.assign(prob.observations.size(), 1);

  ceres_ba::AbortCallback callback(abort, cfg.keep_progress_on_abort);
  auto run_stage = [&](int iterations, bool robust) {
    ceres::Problem::Options popts;
    popts.loss_function_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem problem(popts);
    std::vector<char> camera_used(prob.cameras.size(), 0);
    for (size_t i = 0; i < prob.observations.size(); ++i) {
      if (!res.inlier[i]) continue;
      const auto& o = prob.observations[i];
      const auto& cam = prob.cameras[o.camera];
      ceres::LossFunction* loss =
          robust ? new ceres::HuberLoss(std::sqrt(o.u_right >= 0 ? cfg.chi2_stereo : cfg.chi2_mono)) : nullptr;
      problem.AddResidualBlock(make_cost(cam, o), loss, poses[o.camera].data(), pts[o.point].data());
      camera_used[o.camera] = 1;
    }
    for (size_t c = 0; c < prob.cameras.size(); ++c)
      if (camera_used[c] && prob.cameras[c].fixed) problem.SetParameterBlockConstant(poses[c].data());
    if (problem.NumResidualBlocks() == 0) return;
    ceres::Solver::Options opts;
    opts.linear_solver_type = ceres::SPARSE_SCHUR;
    opts.max_num_iterations = iterations;
    opts.num_threads = cfg.threads;
    opts.logging_type = ceres::SILENT;
    if (abort) opts.callbacks.push_back(&callback);
    ceres::Solver::Summary summary;
    ceres::Solve(opts, &problem, &summary);
    ceres_ba::accumulate(summary, res);
  };
  auto classify = [&] {
    for (size_t i = 0; i < prob.observations.size(); ++i) {
      const auto& o = prob.observations[i];
      BaCamera cam = prob.cameras[o.camera];
      cam.T_cam_world = from_param(poses[o.camera].data());
      const Eigen::Vector3d p(pts[o.point][0], pts[o.point][1], pts[o.point][2]);
      res.inlier[i] = ba_observation_chi2(cam, p, o) <= (o.u_right >= 0 ? cfg.chi2_stereo : cfg.chi2_mono);
    }
  };

  run_stage(cfg.first_iterations, true);
  if (!res.aborted && cfg.second_iterations > 0) {
    classify();
    run_stage(cfg.second_iterations, false);
  }
  classify();
  for (const auto& p : poses) res.T_cam_world.push_back(from_param(p.data()));
  for (const auto& p : pts) res.points.emplace_back(p[0], p[1], p[2]);
  return res;
}

}  // namespace cslam
