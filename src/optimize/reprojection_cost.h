#pragma once
// Reprojection residuals for ORB-SLAM2-style RGB-D observations, templated for Ceres autodiff.
// Pose parameter block: T_cam_world as [angle-axis (3), translation (3)]. Point block: p_world (3).
// A "stereo" observation adds the virtual right coordinate u_r = u - bf / z as a third residual.
// Residuals are whitened by sqrt(1 / sigma^2 of the keypoint's pyramid level).
#include <ceres/rotation.h>

#include <Eigen/Core>

namespace cslam {

struct StereoIntrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0, bf = 0;
};

template <typename T>
inline void project_stereo(const StereoIntrinsics& k, const T* pose, const T* point, T* uvr) {
  T p[3];
  ceres::AngleAxisRotatePoint(pose, point, p);
  p[0] += pose[3];
  p[1] += pose[4];
  p[2] += pose[5];
  const T inv_z = T(1.0) / p[2];
  uvr[0] = T(k.fx) * p[0] * inv_z + T(k.cx);
  uvr[1] = T(k.fy) * p[1] * inv_z + T(k.cy);
  uvr[2] = uvr[0] - T(k.bf) * inv_z;
}

// Residual of a keypoint observed at (u, v) [and u_r], pose and point both parameters.
template <int kResiduals>
struct ReprojectionCost {
  ReprojectionCost(const StereoIntrinsics& k, double u, double v, double ur, double sqrt_info)
      : k(k), u(u), v(v), ur(ur), w(sqrt_info) {}
  template <typename T>
  bool operator()(const T* pose, const T* point, T* r) const {
    T uvr[3];
    project_stereo(k, pose, point, uvr);
    r[0] = T(w) * (uvr[0] - T(u));
    r[1] = T(w) * (uvr[1] - T(v));
    if constexpr (kResiduals == 3) r[2] = T(w) * (uvr[2] - T(ur));
    return true;
  }
  StereoIntrinsics k;
  double u, v, ur, w;
};

// Same residual with the point held fixed (pose-only optimisation).
template <int kResiduals>
struct PoseOnlyReprojectionCost {
  PoseOnlyReprojectionCost(const StereoIntrinsics& k, const Eigen::Vector3d& p, double u, double v, double ur,
                           double sqrt_info)
      : inner(k, u, v, ur, sqrt_info), p(p) {}
  template <typename T>
  bool operator()(const T* pose, T* r) const {
    const T point[3] = {T(p.x()), T(p.y()), T(p.z())};
    return inner(pose, point, r);
  }
  ReprojectionCost<kResiduals> inner;
  Eigen::Vector3d p;
};

}  // namespace cslam
