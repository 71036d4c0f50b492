#pragma once
// Back-projection of registered RGB-D images to coloured 3D points.
#include <vector>

#include <opencv2/core.hpp>

#include "cloud/point_cloud.h"
#include "geometry/camera.h"
#include "geometry/se3.h"

namespace cslam {

// Per-pixel undistorted viewing rays (x/z, y/z) of a camera, computed once per camera with
// PinholeCamera::undistort_pixels (depth is registered to the distorted colour image).
class RayTable {
 public:
  explicit RayTable(const PinholeCamera& camera);
  const PinholeCamera& camera() const { return camera_; }
  const float* ray(int u, int v) const { return &rays_[2 * (size_t(v) * size_t(camera_.width) + size_t(u))]; }
  // Largest squared normalised radius inside the image (projections beyond it are rejected:
  // the distortion polynomial folds back outside the calibrated field of view).
  float max_radius2() const { return max_r2_; }

 private:
  PinholeCamera camera_;
  std::vector<float> rays_;
  float max_r2_ = 0;
};

// A rigid transform in float for per-pixel loops (the identity for nullptr).
struct RigidF {
  Eigen::Matrix3f R = Eigen::Matrix3f::Identity();
  Eigen::Vector3f t = Eigen::Vector3f::Zero();
  explicit RigidF(const SE3* T = nullptr) {
    if (T) R = T->R().cast<float>(), t = T->translation().cast<float>();
  }
  Eigen::Vector3f operator*(const Eigen::Vector3f& p) const { return R * p + t; }
};

// Projects camera-frame points to the nearest pixel of the table's camera (forward distortion in
// float, as the back-projection's rays were made): false behind the camera, beyond the calibrated
// field of view (max_radius2) or outside the image.
class PixelProjector {
 public:
  explicit PixelProjector(const RayTable& rays);
  bool operator()(const Eigen::Vector3f& p_cam, int& u, int& v) const {
    if (p_cam.z() <= 1e-3f) return false;
    const float iz = 1.0f / p_cam.z();
    float xn = p_cam.x() * iz, yn = p_cam.y() * iz;
    const float r2 = xn * xn + yn * yn;
    if (r2 > max_r2_) return false;
    if (distorted_) {
      const float radial = 1 + r2 * (k1_ + r2 * (k2_ + r2 * k3_));
      const float xd = xn * radial + 2 * p1_ * xn * yn + p2_ * (r2 + 2 * xn * xn);
      const float yd = yn * radial + p1_ * (r2 + 2 * yn * yn) + 2 * p2_ * xn * yn;
      xn = xd;
      yn = yd;
    }
    const float uf = fx_ * xn + cx_ + 0.5f, vf = fy_ * yn + cy_ + 0.5f;  // round to nearest
    if (!(uf >= 0.0f && vf >= 0.0f && uf < float(width_) && vf < float(height_))) return false;
    u = int(uf);
    v = int(vf);
    return true;
  }

 private:
  float fx_, fy_, cx_, cy_, k1_, k2_, p1_, p2_, k3_, max_r2_;
  bool distorted_;
  int width_, height_;
};

struct BackprojectParams {
  double min_depth = 0.3, max_depth = 4.0;
  int stride = 1;
};

// Appends the valid pixels (every stride-th in u and v, depth within range) as world points
// with their colour. bgr: CV_8UC3, depth: CV_16UC1, both of the table's camera size (checked
// by the caller). T_world_cam places the depth image. When the colour image was taken elsewhere
// (T_colourcam_depthcam: the camera moved between the two captures), each point takes the colour
// where it projects in the colour image (the same pixel if it projects outside). Returns the
// number of points added.
std::size_t backproject(const cv::Mat& bgr, const cv::Mat& depth, const RayTable& rays, const SE3& T_world_cam,
                        const BackprojectParams& params, ColoredCloud& out, const SE3* T_colourcam_depthcam = nullptr);

}  // namespace cslam
