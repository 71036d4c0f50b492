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

  bool linearize_at(const double* x, SmallLinearization<6>& lin) const {
    PoseLinearizationPoint T;
    T.set(x);
    lin.H.setZero();
    lin.g.setZero();
    double cost = 0;
    Eigen::Vector3d uvr;
    Matrix36d J;
    Eigen::Matrix3d J_point;
    for (size_t i = 0; i < obs_.size(); ++i) {
      if (!inlier_[i]) continue;
      const PoseObservation& o = obs_[i];
      project_with_jacobians(k_, T, o.p_world, uvr, J, J_point);
      const WeightedResidual wr =
          weighted_residual(uvr, o.uv, o.u_right, o.inv_sigma2, robust_, delta_mono_, delta_stereo_);
      const bool stereo = wr.stereo;
      const Eigen::Vector3d& r = wr.r;
      const double w = wr.weight;
      cost += wr.cost;
      if (stereo) {
        lin.H.noalias() += (w * J.transpose()) * J;
        lin.g.noalias() += (w * J.transpose()) * r;
      } else {
        const auto J2 = J.topRows<2>();
        lin.H.noalias() += (w * J2.transpose()) * J2;
        lin.g.noalias() += (w * J2.transpose()) * r.head<2>();
      }
    }
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
