#pragma once
// Ceres parametrisation of similarities and the cost functors of Sim3 refinement and pose graphs.
// A Sim3 is two parameter blocks: [angle-axis (3), translation (3)] and [log-scale (1)], so a
// fixed scale is simply a constant block. Functors are templated for autodiff.
#include <array>
#include <cmath>

#include <ceres/rotation.h>

#include "geometry/se3.h"
#include "optimize/reprojection_cost.h"

namespace cslam {

struct Sim3Param {
  std::array<double, 6> pose{};  // angle-axis, translation
  double log_scale = 0;
};

inline Sim3Param to_sim3_param(const Sim3& S) {
  Sim3Param p;
  const Eigen::Quaterniond& q = S.rotation();
  const double quat[4] = {q.w(), q.x(), q.y(), q.z()};
  ceres::QuaternionToAngleAxis(quat, p.pose.data());
  for (int i = 0; i < 3; ++i) p.pose[3 + i] = S.translation()[i];
  p.log_scale = std::log(S.scale());
  return p;
}

inline Sim3 from_sim3_param(const double* pose, double log_scale) {
  double quat[4];
  ceres::AngleAxisToQuaternion(pose, quat);
  return Sim3(Eigen::Quaterniond(quat[0], quat[1], quat[2], quat[3]), Eigen::Vector3d(pose[3], pose[4], pose[5]),
              std::exp(log_scale));
}

template <typename T>
inline void pinhole(const StereoIntrinsics& k, const T* p, T* uv) {
  const T inv_z = T(1.0) / p[2];
  uv[0] = T(k.fx) * p[0] * inv_z + T(k.cx);
  uv[1] = T(k.fy) * p[1] * inv_z + T(k.cy);
}

// Image-1 residual of a Sim3 match: project T_view_1 * S_12 * p2 with k1 against uv1, whitened by
// 1/sigma. T_view_1 (fixed; identity by default) is the observing camera of uv1 relative to camera 1.
struct Sim3ReprojectionCost1 {
  Sim3ReprojectionCost1(const StereoIntrinsics& k1, const Eigen::Vector3d& p2, const Eigen::Vector2d& uv1,
                        double sqrt_info, const SE3& T_view_1 = SE3())
      : k(k1),
        p(p2),
        uv(uv1),
        w(sqrt_info),
        R_view(T_view_1.rotation().toRotationMatrix()),
        t_view(T_view_1.translation()) {}
  template <typename T>
  bool operator()(const T* pose, const T* log_scale, T* r) const {
    const T src[3] = {T(p.x()), T(p.y()), T(p.z())};
    T q[3];
    ceres::AngleAxisRotatePoint(pose, src, q);
    const T s = exp(log_scale[0]);
    for (int i = 0; i < 3; ++i) q[i] = s * q[i] + pose[3 + i];
    T v[3];
    for (int i = 0; i < 3; ++i)
      v[i] = T(R_view(i, 0)) * q[0] + T(R_view(i, 1)) * q[1] + T(R_view(i, 2)) * q[2] + T(t_view[i]);
    T proj[2];
    pinhole(k, v, proj);
    r[0] = T(w) * (proj[0] - T(uv.x()));
    r[1] = T(w) * (proj[1] - T(uv.y()));
    return true;
  }
  StereoIntrinsics k;
  Eigen::Vector3d p;
  Eigen::Vector2d uv;
  double w;
  Eigen::Matrix3d R_view;
  Eigen::Vector3d t_view;
};

// Image-2 residual: project S_21 * p1 = (1/s) R^T (p1 - t) with k2 against uv2.
struct Sim3ReprojectionCost2 {
  Sim3ReprojectionCost2(const StereoIntrinsics& k2, const Eigen::Vector3d& p1, const Eigen::Vector2d& uv2,
                        double sqrt_info)
      : k(k2), p(p1), uv(uv2), w(sqrt_info) {}
  template <typename T>
  bool operator()(const T* pose, const T* log_scale, T* r) const {
    const T minus_aa[3] = {-pose[0], -pose[1], -pose[2]};
    const T d[3] = {T(p.x()) - pose[3], T(p.y()) - pose[4], T(p.z()) - pose[5]};
    T q[3];
    ceres::AngleAxisRotatePoint(minus_aa, d, q);
    const T inv_s = exp(-log_scale[0]);
    for (int i = 0; i < 3; ++i) q[i] *= inv_s;
    T proj[2];
    pinhole(k, q, proj);
    r[0] = T(w) * (proj[0] - T(uv.x()));
    r[1] = T(w) * (proj[1] - T(uv.y()));
    return true;
  }
  StereoIntrinsics k;
  Eigen::Vector3d p;
  Eigen::Vector2d uv;
  double w;
};

// Pose-graph edge between nodes i and j (camera-to-world similarities S_wi, S_wj) with measured
// S_ij. Error E = S_ij^-1 * S_wi^-1 * S_wj, residual sqrt(weight) * [angle-axis of R_E,
// t_E, log s_E] (first-order approximation of log(E); 6 residuals drop the scale term).
template <int kResiduals>
struct PoseGraphEdgeCost {
  static_assert(kResiduals == 6 || kResiduals == 7, "6 (SE3) or 7 (Sim3) residuals");
  PoseGraphEdgeCost(const Sim3& S_ij, double weight) : sqrt_w(std::sqrt(weight)) {
    const Sim3 inv = S_ij.inverse();
    const Eigen::Quaterniond& q = inv.rotation();
    q_inv = {q.w(), q.x(), q.y(), q.z()};
    t_meas = S_ij.translation();
    inv_s_meas = 1.0 / S_ij.scale();
    log_s_meas = std::log(S_ij.scale());
  }
  template <typename T>
  bool operator()(const T* pose_i, const T* log_s_i, const T* pose_j, const T* log_s_j, T* r) const {
    // Relative D = S_wi^-1 S_wj: R_i^T R_j, (1/s_i) R_i^T (t_j - t_i), s_j / s_i.
    T qi[4], qj[4];
    ceres::AngleAxisToQuaternion(pose_i, qi);
    ceres::AngleAxisToQuaternion(pose_j, qj);
    const T qi_conj[4] = {qi[0], -qi[1], -qi[2], -qi[3]};
    T q_d[4], q_e[4];
    ceres::QuaternionProduct(qi_conj, qj, q_d);
    const T qm[4] = {T(q_inv[0]), T(q_inv[1]), T(q_inv[2]), T(q_inv[3])};
    ceres::QuaternionProduct(qm, q_d, q_e);
    ceres::QuaternionToAngleAxis(q_e, r);

    const T minus_aa_i[3] = {-pose_i[0], -pose_i[1], -pose_i[2]};
    const T dt[3] = {pose_j[3] - pose_i[3], pose_j[4] - pose_i[4], pose_j[5] - pose_i[5]};
    T t_d[3];
    ceres::AngleAxisRotatePoint(minus_aa_i, dt, t_d);
    const T inv_s_i = exp(-log_s_i[0]);
    // t_E = (1/s_m) R_m^T (t_D - t_m) = R_{m^-1} (t_D - t_m) / s_m.
    const T diff[3] = {inv_s_i * t_d[0] - T(t_meas.x()), inv_s_i * t_d[1] - T(t_meas.y()),
                       inv_s_i * t_d[2] - T(t_meas.z())};
    T t_e[3];
    ceres::UnitQuaternionRotatePoint(qm, diff, t_e);
    for (int k = 0; k < 3; ++k) r[3 + k] = T(inv_s_meas) * t_e[k];
    if constexpr (kResiduals == 7) r[6] = log_s_j[0] - log_s_i[0] - T(log_s_meas);
    for (int k = 0; k < kResiduals; ++k) r[k] *= T(sqrt_w);
    return true;
  }
  double sqrt_w;
  std::array<double, 4> q_inv{};  // measured rotation inverse, (w, x, y, z)
  Eigen::Vector3d t_meas;
  double inv_s_meas = 1, log_s_meas = 0;
};

}  // namespace cslam
