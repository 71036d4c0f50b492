// Bundle adjustment in two stages (Huber kernel, then the inliers without kernel), each one a
// Levenberg-Marquardt solve over the current inliers followed by a re-classification of every
// observation, all on the Schur-complement solver of schur_ba.h (a dense reduced camera system
// for local-BA sizes, a block-sparse one beyond).
#include "optimize/bundle_adjustment.h"

#include <cmath>
#include <limits>

#include "optimize/pose_param.h"
#include "optimize/reprojection_chi2.h"
#include "optimize/schur_ba.h"

namespace cslam {

double ba_observation_chi2(const BaCamera& cam, const Eigen::Vector3d& pw, const BaObservation& o) {
  return reprojection_chi2(cam.intrinsics, cam.T_cam_world * pw, o.uv, o.u_right, o.inv_sigma2);
}

BaResult bundle_adjust(const BaProblem& prob, const BaConfig& cfg, const std::atomic<bool>* abort) {
  BaResult res;
  std::vector<std::array<double, 6>> poses;
  poses.reserve(prob.cameras.size());
  for (const auto& c : prob.cameras) poses.push_back(to_param(c.T_cam_world));
  std::vector<Eigen::Vector3d> pts = prob.points;
  res.inlier.assign(prob.observations.size(), 1);

  auto run_stage = [&](int iterations, bool robust) {
    bool any = false;
    for (char c : res.inlier) any = any || c;
    if (!any) return;
    // As Ceres: a stage that ends unusable (aborted, numerical failure) leaves the values it
    // started from.
    const auto poses_before = poses;
    const auto pts_before = pts;
    const LmOutcome lm = schur_ba_stage(prob, res.inlier, robust, cfg, iterations, abort, poses, pts);
    if (!lm.usable) {
      poses = poses_before;
      pts = pts_before;
    }
    if (res.iterations == 0) res.initial_cost = lm.initial_cost;
    res.final_cost = lm.final_cost;
    res.iterations += lm.iterations;
    res.converged = lm.usable;
    if (lm.aborted) res.aborted = true;
    if (lm.aborted && lm.usable) res.partial = true;
  };
  auto classify = [&] {
    std::vector<BaCamera> cams = prob.cameras;
    for (size_t c = 0; c < cams.size(); ++c) cams[c].T_cam_world = from_param(poses[c].data());
    for (size_t i = 0; i < prob.observations.size(); ++i) {
      const auto& o = prob.observations[i];
      res.inlier[i] =
          ba_observation_chi2(cams[o.camera], pts[o.point], o) <= (o.u_right >= 0 ? cfg.chi2_stereo : cfg.chi2_mono);
    }
  };

  run_stage(cfg.first_iterations, true);
  if (!res.aborted && cfg.second_iterations > 0) {
    classify();
    run_stage(cfg.second_iterations, false);
  }
  classify();
  for (const auto& p : poses) res.T_cam_world.push_back(from_param(p.data()));
  res.points = std::move(pts);
  return res;
}

}  // namespace cslam
