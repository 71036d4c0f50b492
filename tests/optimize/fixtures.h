#pragma once
// Synthetic correspondences for optimisation tests: points in front of cameras, exact projections.
#include <random>
#include <vector>

#include "geometry/se3.h"
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

}  // namespace cslam::test
