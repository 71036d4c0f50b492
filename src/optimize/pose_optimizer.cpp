// Pose-only optimisation: fixed-size Levenberg-Marquardt with analytic Jacobians. It minimises
// the cost of the Ceres reference (optimize_pose_ceres: 0.5 sum rho(chi2), Huber rho in the
// robust rounds) in the same parameters with the same step control (lm_driver.h), so it ends
// where Ceres ends, without building a Ceres problem per round (the LM plumbing:
// small_lm_problem.h). The only heap allocation per call is the result's inlier vector.
#include "optimize/pose_optimizer.h"

#include <array>
#include <cmath>

#include "optimize/lm_driver.h"
#include "optimize/small_lm_problem.h"
#include "optimize/pose_param.h"
#include "optimize/reprojection_chi2.h"
#include "optimize/se3_projection.h"

namespace cslam {

namespace {

class PoseProblem : public SmallLmProblem<6, PoseProblem> {
 public:
  PoseProblem(const std::vector<PoseObservation>& obs, const std::vector<char>& inlier, const StereoIntrinsics& k,
              bool robust, const PoseOptimizationConfig& cfg, std::array<double, 6>& x)
      : SmallLmProblem(x, 6),
        obs_(obs),
        inlier_(inlier),
        k_(k),
        robust_(robust),
        delta_mono_(std::sqrt(cfg.chi2_mono)),
        delta_stereo_(std::sqrt(cfg.chi2_stereo)) {}

  // The cost linearize_at computes, summed in the same order, without derivatives.
  double cost_at(const double* x) const {
    PoseLinearizationPoint T;
    T.set_transform(x);
    double cost = 0;
    for (size_t i = 0; i < obs_.size(); ++i) {
      if (!inlier_[i]) continue;
      const PoseObservation& o = obs_[i];
      cost += weighted_residual(project_point(k_, T, o.p_world), o.uv, o.u_right, o.inv_sigma2, robust_, delta_mono_,
                                delta_stereo_)
                  .cost;
    }
    return 0.5 * cost;
  }

  // J^T W J and J^T W r summed in the camera frame's motion (camera_motion_jacobian: no rotation
  // Jacobian per observation, the upper triangle only), then carried to the parameters once.
  bool linearize_at(const double* x, SmallLinearization<6>& lin) const {
    PoseLinearizationPoint T;
    T.set(x);
    Matrix6d H = Matrix6d::Zero();
    Vector6d g = Vector6d::Zero();
    double cost = 0;
    for (size_t i = 0; i < obs_.size(); ++i) {
      if (!inlier_[i]) continue;
      const PoseObservation& o = obs_[i];
      const Eigen::Vector3d pc = T.R * o.p_world + T.t;
      const double iz = 1.0 / pc.z();
      const WeightedResidual wr = weighted_residual(project_camera_point(k_, pc, iz), o.uv, o.u_right, o.inv_sigma2,
                                                    robust_, delta_mono_, delta_stereo_);
      cost += wr.cost;
      const Matrix36d J = camera_motion_jacobian(k_, pc, iz);
      const int rows = wr.stereo ? 3 : 2;
      for (int r = 0; r < rows; ++r) {
        const double wr_r = wr.weight * wr.r(r);
        for (int a = 0; a < 6; ++a) {
          const double wj = wr.weight * J(r, a);
          g(a) += J(r, a) * wr_r;
          for (int b = a; b < 6; ++b) H(a, b) += wj * J(r, b);
        }
      }
    }
    H.triangularView<Eigen::StrictlyLower>() = H.transpose();
    const Matrix6d M = param_map(T);
    lin.H.noalias() = M.transpose() * H * M;
    lin.g.noalias() = M.transpose() * g;
    lin.cost = 0.5 * cost;
    return std::isfinite(lin.cost) && lin.H.allFinite() && lin.g.allFinite();
  }

 private:
  const std::vector<PoseObservation>& obs_;
  const std::vector<char>& inlier_;
  const StereoIntrinsics& k_;
  const bool robust_;
  const double delta_mono_, delta_stereo_;
};

double chi2_at(const Eigen::Matrix3d& R, const Eigen::Vector3d& t, const PoseObservation& o,
               const StereoIntrinsics& k) {
  return reprojection_chi2(k, R * o.p_world + t, o.uv, o.u_right, o.inv_sigma2);
}

}  // namespace

double observation_chi2(const SE3& T, const PoseObservation& o, const StereoIntrinsics& k) {
  return chi2_at(T.R(), T.translation(), o, k);
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
  std::array<double, 6> x = to_param(initial);
  for (int round = 0; round < cfg.rounds; ++round) {
    int used = 0;
    for (char c : res.inlier) used += c ? 1 : 0;
    if (used < 3) break;
    const std::array<double, 6> x_before = x;
    PoseProblem problem(obs, res.inlier, k, round < cfg.robust_rounds, cfg, x);
    const LmOutcome lm = levenberg_marquardt(problem, cfg.iterations_per_round, nullptr, cfg.min_step_decrease);
    if (!lm.usable) x = x_before;  // as Ceres: an unusable solve leaves the parameters
    res.final_cost = lm.final_cost;
    res.converged = lm.converged;
    // Re-classify every observation (outliers may come back) against the new pose.
    const SE3 T = from_param(x.data());
    const Eigen::Matrix3d R = T.R();
    for (size_t i = 0; i < obs.size(); ++i)
      res.inlier[i] = chi2_at(R, T.translation(), obs[i], k) <= (obs[i].u_right >= 0 ? cfg.chi2_stereo : cfg.chi2_mono);
  }
  res.T_cam_world = from_param(x.data());
  res.num_inliers = 0;
  for (char c : res.inlier) res.num_inliers += c ? 1 : 0;
  return res;
}

}  // namespace cslam
