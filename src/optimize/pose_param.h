#pragma once
// Conversion between SE3 and the 6-vector [angle-axis, translation] used as Ceres parameter block.
#include <array>

#include <ceres/rotation.h>

#include "geometry/se3.h"

namespace cslam {

inline std::array<double, 6> to_param(const SE3& T) {
  std::array<double, 6> p{};
  const Eigen::Quaterniond& q = T.rotation();
  const double quat[4] = {q.w(), q.x(), q.y(), q.z()};
  ceres::QuaternionToAngleAxis(quat, p.data());
  p[3] = T.translation().x();
  p[4] = T.translation().y();
  p[5] = T.translation().z();
  return p;
}

inline SE3 from_param(const double* p) {
  double quat[4];
  ceres::AngleAxisToQuaternion(p, quat);
  return SE3(Eigen::Quaterniond(quat[0], quat[1], quat[2], quat[3]), Eigen::Vector3d(p[3], p[4], p[5]));
}

}  // namespace cslam
