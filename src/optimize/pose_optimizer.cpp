#include "optimize/pose_optimizer.h"

#include <cmath>

#include <ceres/ceres.h>

#include "optimize/pose_param.h"

namespace cslam {

double observation_chi2(const SE3& T, const PoseObservation& o, const StereoIntrinsics& k) {
  const Eigen::Vector3d p = T * o.p_world;
  if (p.z() <= 0) return std::numeric_limits<double>::infinity();
  const double u = k.fx * p.x() / p.z() + k.cx, v = k.fy * p.y() / p.z() + k.cy;
  double e2 = (u - o.uv.x()) * (u - o.uv.x()) + (v - o.uv.y()) * (v - o.uv.y());
  if (o.u_right >= 0) {
    const double ur = u - k.bf / p.z();
    e2 += (ur - o.u_right) * (ur - o.u_right);
  }
  return e2 * o.inv_sigma2;
}

PoseOptimizationResult optimize_pose(const SE3& initial, const std::vector<PoseObservation>& obs,
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
      ceres::LossFunction* loss = round < cfg.robust_rounds ? new ceres::HuberLoss(std::sqrt(stereo ? cfg.chi2_stereo : cfg.chi2_mono)) : nullptr;
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

}  // namespace cslam
