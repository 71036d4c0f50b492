#pragma once
// Whitened squared reprojection error of one RGB-D ("stereo") observation, the chi2 that bundle
// adjustment and pose optimisation compare with their 5.991 (2 dof) / 7.815 (3 dof) thresholds.
#include <limits>

#include <Eigen/Core>

#include "optimize/reprojection_cost.h"

namespace cslam {

// p: the point in camera coordinates; uv: the undistorted keypoint; u_right < 0: monocular (no
// virtual right coordinate u_r = u - bf / z); inv_sigma2 of the keypoint's level. Infinite behind
// the camera.
inline double reprojection_chi2(const StereoIntrinsics& k, const Eigen::Vector3d& p, const Eigen::Vector2d& uv,
                                double u_right, double inv_sigma2) {
  if (p.z() <= 0) return std::numeric_limits<double>::infinity();
  const double u = k.fx * p.x() / p.z() + k.cx, v = k.fy * p.y() / p.z() + k.cy;
  double e2 = (u - uv.x()) * (u - uv.x()) + (v - uv.y()) * (v - uv.y());
  if (u_right >= 0) {
    const double ur = u - k.bf / p.z();
    e2 += (ur - u_right) * (ur - u_right);
  }
  return e2 * inv_sigma2;
}

}  // namespace cslam
