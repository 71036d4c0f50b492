#pragma once
// Analytic derivatives of the RGB-D ("stereo") reprojection for the fast optimisers.
// The pose parameters are the ones of the Ceres reference (pose_param.h): T_cam_world as
// [angle-axis w (3), translation t (3)], p_cam = R(w) p_world + t, updated additively
// (x <- x + delta), so the fast solvers take the same Levenberg-Marquardt steps as Ceres.
// With the right Jacobian Jr of SO3, R(w + d) ~ R(w) Exp(Jr(w) d), hence
// d p_cam / d w = -R [p_world]x Jr(w), d p_cam / d t = I, d p_cam / d p_world = R.
#include <cmath>

#include <ceres/rotation.h>

#include <Eigen/Core>

#include "geometry/se3.h"
#include "optimize/reprojection_cost.h"

namespace cslam {

using Matrix36d = Eigen::Matrix<double, 3, 6>;
using Matrix63d = Eigen::Matrix<double, 6, 3>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

// Right Jacobian of SO3 at the angle-axis vector w.
inline Eigen::Matrix3d so3_right_jacobian(const Eigen::Vector3d& w) {
  const double theta2 = w.squaredNorm();
  const Eigen::Matrix3d W = skew(w);
  if (theta2 < 1e-10) return Eigen::Matrix3d::Identity() - 0.5 * W + (1.0 / 6.0) * W * W;
  const double theta = std::sqrt(theta2);
  return Eigen::Matrix3d::Identity() - (1.0 - std::cos(theta)) / theta2 * W +
         (theta - std::sin(theta)) / (theta2 * theta) * W * W;
}

// Everything about one camera pose the per-observation derivatives need (computed once per
// camera and evaluation).
struct PoseLinearizationPoint {
  Eigen::Matrix3d R, Jr;
  Eigen::Vector3d t;
  void set(const double* param) {
    set_transform(param);
    const Eigen::Vector3d w(param[0], param[1], param[2]);
    Jr = so3_right_jacobian(w);
  }
  // R and t only: enough to project (project_point), not to differentiate.
  void set_transform(const double* param) {
    ceres::AngleAxisToRotationMatrix(param, ceres::ColumnMajorAdapter3x3(R.data()));
    t = Eigen::Vector3d(param[3], param[4], param[5]);
  }
};

// (u, v, u_right) of the camera-frame point pc, with iz = 1 / pc.z().
inline Eigen::Vector3d project_camera_point(const StereoIntrinsics& k, const Eigen::Vector3d& pc, double iz) {
  Eigen::Vector3d uvr;
  uvr.x() = k.fx * pc.x() * iz + k.cx;
  uvr.y() = k.fy * pc.y() * iz + k.cy;
  uvr.z() = uvr.x() - k.bf * iz;
  return uvr;
}

// (u, v, u_right) of p_world seen from the pose (R and t of T set), the same values as the
// projections with derivatives below.
inline Eigen::Vector3d project_point(const StereoIntrinsics& k, const PoseLinearizationPoint& T,
                                     const Eigen::Vector3d& pw) {
  const Eigen::Vector3d pc = T.R * pw + T.t;
  return project_camera_point(k, pc, 1.0 / pc.z());
}

// The derivative of (u, v, u_right) w.r.t. the point in camera coordinates pc (iz = 1 / pc.z()).
inline Eigen::Matrix3d camera_point_jacobian(const StereoIntrinsics& k, const Eigen::Vector3d& pc, double iz) {
  const double iz2 = iz * iz;
  Eigen::Matrix3d d_pc;
  d_pc << k.fx * iz, 0, -k.fx * pc.x() * iz2,  //
      0, k.fy * iz, -k.fy * pc.y() * iz2,      //
      k.fx * iz, 0, (k.bf - k.fx * pc.x()) * iz2;
  return d_pc;
}

// (u, v, u_right) of p_world seen from the pose and its derivative w.r.t. the point (3x3); returns
// the derivative of (u, v, u_right) w.r.t. the point in camera coordinates, which the pose
// Jacobian needs. Alone it serves observations from cameras held fixed.
inline Eigen::Matrix3d project_with_point_jacobian(const StereoIntrinsics& k, const PoseLinearizationPoint& T,
                                                   const Eigen::Vector3d& pw, Eigen::Vector3d& uvr,
                                                   Eigen::Matrix3d& J_point) {
  const Eigen::Vector3d pc = T.R * pw + T.t;
  const double iz = 1.0 / pc.z();
  uvr = project_camera_point(k, pc, iz);
  const Eigen::Matrix3d d_pc = camera_point_jacobian(k, pc, iz);
  J_point.noalias() = d_pc * T.R;
  return d_pc;
}

// (u, v, u_right) of p_world seen from the pose, and its derivatives w.r.t. the pose
// parameters (3x6) and the point (3x3). Rows beyond the observation's residual count are
// ignored by the callers.
inline void project_with_jacobians(const StereoIntrinsics& k, const PoseLinearizationPoint& T,
                                   const Eigen::Vector3d& pw, Eigen::Vector3d& uvr, Matrix36d& J_pose,
                                   Eigen::Matrix3d& J_point) {
  const Eigen::Matrix3d d_pc = project_with_point_jacobian(k, T, pw, uvr, J_point);
  // Row b of J_point times -[pw]x is (pw x b)^T.
  Eigen::Matrix3d C;
  for (int r = 0; r < 3; ++r) C.row(r) = pw.cross(J_point.row(r).transpose()).transpose();
  J_pose.leftCols<3>().noalias() = C * T.Jr;
  J_pose.rightCols<3>() = d_pc;
}

// The pose Jacobian in two factors: d uvr / d param = camera_motion_jacobian(k, pc, iz) *
// param_map(T). The first is the derivative by a small motion of the point in the camera frame
// (pc + w x pc + dt: rotation w, then translation dt), cheap per observation; the second carries
// that motion to the parameters [angle-axis, translation] and is the same for every observation
// of one pose: with A = R Jr, M = [[A, 0], [[t]x A, I]] (from R [p]x = [R p]x R). A solver sums
// J_motion^T W J_motion over a pose's observations and applies M once.
inline Matrix36d camera_motion_jacobian(const StereoIntrinsics& k, const Eigen::Vector3d& pc, double iz) {
  const Eigen::Matrix3d d_pc = camera_point_jacobian(k, pc, iz);
  Matrix36d J;
  for (int r = 0; r < 3; ++r) {
    const Eigen::Vector3d d = d_pc.row(r).transpose();
    J.block<1, 3>(r, 0) = pc.cross(d).transpose();  // d^T (-[pc]x)
    J.block<1, 3>(r, 3) = d.transpose();
  }
  return J;
}

inline Matrix6d param_map(const PoseLinearizationPoint& T) {
  Matrix6d M = Matrix6d::Zero();
  const Eigen::Matrix3d A = T.R * T.Jr;
  M.topLeftCorner<3, 3>() = A;
  M.bottomLeftCorner<3, 3>() = skew(T.t) * A;
  M.bottomRightCorner<3, 3>().setIdentity();
  return M;
}

// Huber kernel on a squared whitened error s (Ceres' HuberLoss(delta)): rho(s) = s inside
// delta^2, 2 delta sqrt(s) - delta^2 beyond; weight = rho'(s). Ceres' residual correction for
// this kernel (rho'' <= 0) scales residuals and Jacobians by sqrt(rho'), i.e. plain IRLS.
struct HuberValue {
  double rho, weight;
};
inline HuberValue huber(double s, double delta, double delta2) {
  if (s <= delta2) return {s, 1.0};
  const double r = std::sqrt(s);
  return {2.0 * delta * r - delta2, delta / r};
}

// One observation's residual (u, v[, u_r] predicted minus measured; the third entry 0 for a
// monocular one), its cost contribution and its information weight inv_sigma2 * rho'(s).
struct WeightedResidual {
  Eigen::Vector3d r;
  double cost, weight;
  bool stereo;
};
inline WeightedResidual weighted_residual(const Eigen::Vector3d& uvr, const Eigen::Vector2d& uv, double u_right,
                                          double inv_sigma2, bool robust, double delta_mono, double delta_stereo) {
  WeightedResidual out;
  out.stereo = u_right >= 0;
  out.r = Eigen::Vector3d(uvr.x() - uv.x(), uvr.y() - uv.y(), out.stereo ? uvr.z() - u_right : 0.0);
  const double s = out.r.squaredNorm() * inv_sigma2;
  out.weight = inv_sigma2;
  out.cost = s;
  if (robust) {
    const double d = out.stereo ? delta_stereo : delta_mono;
    const HuberValue h = huber(s, d, d * d);
    out.cost = h.rho;
    out.weight *= h.weight;
  }
  return out;
}

}  // namespace cslam
