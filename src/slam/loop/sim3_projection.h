#pragma once
// Analytic derivatives of the two reprojection residuals of a Sim3 match (sim3_costs.h's
// Sim3ReprojectionCost1 / Sim3ReprojectionCost2) for the hand-written refinement (sim3_refine.cpp).
// Parameters as in Ceres: x = [angle-axis w (3), translation t (3), log-scale l (1)], updated
// additively, S_12 p = e^l R(w) p + t. With R(w + d) ~ R(w) Exp(Jr(w) d):
//   image 1: v = R_v (e^l R p2 + t) + t_v        dv/dw = -e^l R_v R [p2]x Jr(w), dv/dt = R_v,
//                                                 dv/dl = e^l R_v R p2
//   image 2: q = e^-l R^T (p1 - t) = e^-l R(-w) d  dq/dw = e^-l R^T [d]x Jr(-w), dq/dt = -e^-l R^T,
//                                                 dq/dl = -q
// and the pinhole projection's derivative. Residuals are whitened by 1/sigma as in the functors.
#include <Eigen/Core>

#include <ceres/rotation.h>

#include "geometry/se3.h"
#include "optimize/se3_projection.h"
#include "slam/loop/sim3_ransac.h"

namespace cslam {

using Matrix27d = Eigen::Matrix<double, 2, 7>;

// What both residuals need of x (computed once per evaluation).
struct Sim3LinearizationPoint {
  Eigen::Matrix3d R, Jr, Jr_neg;  // R(w), Jr(w), Jr(-w)
  Eigen::Vector3d t;
  double scale = 1, inv_scale = 1;
  void set_transform(const double* x) {
    ceres::AngleAxisToRotationMatrix(x, ceres::ColumnMajorAdapter3x3(R.data()));
    t = Eigen::Vector3d(x[3], x[4], x[5]);
    scale = std::exp(x[6]);
    inv_scale = std::exp(-x[6]);
  }
  void set(const double* x) {
    set_transform(x);
    const Eigen::Vector3d w(x[0], x[1], x[2]);
    Jr = so3_right_jacobian(w);
    Jr_neg = so3_right_jacobian(-w);
  }
};

// Whitened pixel residual of `pc` (camera coordinates) projected with k against uv, and the
// derivative of the projection with respect to pc (times the whitening) into P if not null.
inline Eigen::Vector2d sim3_pixel_residual(const StereoIntrinsics& k, const Eigen::Vector3d& pc,
                                           const Eigen::Vector2d& uv, double w, Eigen::Matrix<double, 2, 3>* P) {
  const double iz = 1.0 / pc.z();
  const double u = k.fx * pc.x() * iz + k.cx, v = k.fy * pc.y() * iz + k.cy;
  if (P) {
    *P << w * k.fx * iz, 0, -w * k.fx * pc.x() * iz * iz, 0, w * k.fy * iz, -w * k.fy * pc.y() * iz * iz;
  }
  return {w * (u - uv.x()), w * (v - uv.y())};
}

// Image-1 residual of match m (weight w = 1/sigma_1) and, if J is not null, its Jacobian in x.
inline Eigen::Vector2d sim3_residual_1(const Sim3LinearizationPoint& x, const Sim3Correspondence& m,
                                       const StereoIntrinsics& k1, double w, Matrix27d* J) {
  const Eigen::Matrix3d R_view = m.T_view_1.R();
  const Eigen::Vector3d Rp = x.R * m.p2;
  const Eigen::Vector3d v = R_view * (x.scale * Rp + x.t) + m.T_view_1.translation();
  if (!J) return sim3_pixel_residual(k1, v, m.uv1, w, nullptr);
  Eigen::Matrix<double, 2, 3> P;
  const Eigen::Vector2d r = sim3_pixel_residual(k1, v, m.uv1, w, &P);
  const Eigen::Matrix<double, 2, 3> PR = P * R_view;
  J->block<2, 3>(0, 0) = -x.scale * (PR * x.R) * skew(m.p2) * x.Jr;
  J->block<2, 3>(0, 3) = PR;
  J->col(6) = x.scale * (PR * Rp);
  return r;
}

// Image-2 residual of match m (weight w = 1/sigma_2) and, if J is not null, its Jacobian in x.
inline Eigen::Vector2d sim3_residual_2(const Sim3LinearizationPoint& x, const Sim3Correspondence& m,
                                       const StereoIntrinsics& k2, double w, Matrix27d* J) {
  const Eigen::Vector3d d = m.p1 - x.t;
  const Eigen::Vector3d q = x.inv_scale * (x.R.transpose() * d);
  if (!J) return sim3_pixel_residual(k2, q, m.uv2, w, nullptr);
  Eigen::Matrix<double, 2, 3> P;
  const Eigen::Vector2d r = sim3_pixel_residual(k2, q, m.uv2, w, &P);
  const Eigen::Matrix<double, 2, 3> PRt = x.inv_scale * (P * x.R.transpose());
  J->block<2, 3>(0, 0) = PRt * skew(d) * x.Jr_neg;
  J->block<2, 3>(0, 3) = -PRt;
  J->col(6) = -(P * q);
  return r;
}

}  // namespace cslam
