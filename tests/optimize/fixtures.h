#pragma once
// Synthetic correspondences for optimisation tests: points in front of cameras, exact projections.
#include <random>
#include <vector>

#include "geometry/se3.h"
#include "optimize/pose_optimizer.h"
#include "optimize/reprojection_cost.h"

namespace cslam::test {

inline StereoIntrinsics tum_like_intrinsics() { return {517.3, 516.5, 318.6, 255.3, 40.0}; }

inline std::vector<Eigen::Vector3d> random_points_in_front(int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> xy(-1.5, 1.5), z(1.0, 4.0);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < n; ++i) pts.emplace_back(xy(rng), xy(rng), z(rng));
  return pts;
}

inline Eigen::Vector3d project(const StereoIntrinsics& k, const SE3& T_cam_world, const Eigen::Vector3d& pw) {
  const Eigen::Vector3d p = T_cam_world * pw;
  const double u = k.fx * p.x() / p.z() + k.cx;
  return {u, k.fy * p.y() / p.z() + k.cy, u - k.bf / p.z()};
}

inline SE3 small_motion(double angle, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
  return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized())), t);
}

// A tracking-like pose-only problem: n keypoints spread over a 640x480 image at 0.5-6 m, pyramid
// levels 0-7 (sigma 1.2^level px), a fraction with depth ("stereo"), a fraction of gross
// outliers, and a start pose a few degrees / centimetres off (the motion model's error).
struct PoseProblem {
  SE3 truth, start;
  std::vector<PoseObservation> obs;
  std::vector<char> is_outlier;
};

inline PoseProblem random_pose_problem(std::mt19937& rng, int n, double outlier_fraction, double stereo_fraction) {
  const auto k = tum_like_intrinsics();
  std::uniform_real_distribution<double> U(0, 1), S(-1, 1);
  std::normal_distribution<double> N(0, 1);
  PoseProblem p;
  p.truth = small_motion(0.4 * S(rng), {S(rng), S(rng), S(rng) + 2}, {S(rng), S(rng), S(rng)});
  const SE3 T_world_cam = p.truth.inverse();
  for (int i = 0; i < n; ++i) {
    const double u = 640 * U(rng), v = 480 * U(rng), z = 0.5 + 5.5 * U(rng);
    const Eigen::Vector3d pc((u - k.cx) * z / k.fx, (v - k.cy) * z / k.fy, z);
    const int level = int(8 * U(rng) * U(rng));  // more keypoints at the fine levels
    const double sigma = std::pow(1.2, level);
    PoseObservation o;
    o.p_world = T_world_cam * pc;
    o.inv_sigma2 = 1.0 / (sigma * sigma);
    const bool outlier = U(rng) < outlier_fraction;
    const bool stereo = U(rng) < stereo_fraction;
    if (outlier) {
      o.uv = {640 * U(rng), 480 * U(rng)};
      if (stereo) o.u_right = o.uv.x() - 40.0 / (0.5 + 5.5 * U(rng));
    } else {
      o.uv = Eigen::Vector2d(u, v) + 0.7 * sigma * Eigen::Vector2d(N(rng), N(rng));
      if (stereo) o.u_right = u - k.bf / z + 0.7 * sigma * N(rng);
    }
    p.obs.push_back(o);
    p.is_outlier.push_back(outlier);
  }
  p.start = small_motion(0.03 + 0.03 * U(rng), {S(rng), S(rng), S(rng) + 0.1}, 0.05 * Eigen::Vector3d(S(rng), S(rng), S(rng))) * p.truth;
  return p;
}

}  // namespace cslam::test
