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
  // True if `other` has the same intrinsics, distortion and size.
  bool matches(const PinholeCamera& other) const;
  const float* ray(int u, int v) const { return &rays_[2 * (size_t(v) * size_t(camera_.width) + size_t(u))]; }
  // Largest squared normalised radius inside the image (projections beyond it are rejected:
  // the distortion polynomial folds back outside the calibrated field of view).
  float max_radius2() const { return max_r2_; }

 private:
  PinholeCamera camera_;
  std::vector<float> rays_;
  float max_r2_ = 0;
};

struct BackprojectParams {
  double min_depth = 0.3, max_depth = 4.0;
  int stride = 1;
};

// Appends the valid pixels (every stride-th in u and v, depth within range) as world points
// with their colour. bgr: CV_8UC3, depth: CV_16UC1, both of the table's camera size (checked
// by the caller). Returns the number of points added.
std::size_t backproject(const cv::Mat& bgr, const cv::Mat& depth, const RayTable& rays, const SE3& T_world_cam,
                        const BackprojectParams& params, ColoredCloud& out);

}  // namespace cslam
