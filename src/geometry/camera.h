#pragma once
// Pinhole camera with radial-tangential (k1 k2 p1 p2 k3) distortion, image size and depth factor.
#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace cslam {

// Plausibility bounds of PinholeCamera::validate (docs/security.md, "Camera checks"):
//  - each image side at least 48 px: the ORB extractor (edge_threshold 19) skips a pyramid level
//    whose side is <= 2 * 19 + 8 = 46 px, so a smaller image yields no features at all;
//  - the principal point inside the image, cx in [0, width], cy in [0, height] (no margin: a
//    calibrated centre is always inside; an off-centre crop keeps it inside too);
//  - fx in [0.1, 10] x width and fy in [0.1, 10] x height: a field of view between about 157 and
//    5.7 degrees; a lens outside that is not a pinhole camera this system can track with.
constexpr int kMinCameraSide = 48;
constexpr double kMinFocalPerSide = 0.1, kMaxFocalPerSide = 10.0;

struct PinholeCamera {
  double fx = 525.0, fy = 525.0, cx = 319.5, cy = 239.5;
  // Distortion coefficients in OpenCV order: k1 k2 p1 p2 k3.
  std::array<double, 5> dist{0, 0, 0, 0, 0};
  int width = 640, height = 480;
  // Raw depth value per metre (TUM: 5000 -> 1 unit = 0.2 mm).
  double depth_factor = 5000.0;
  // Multiplicative correction applied after dividing by depth_factor (fr2: 1.031 is sometimes used).
  double depth_scale_correction = 1.0;
  // Rolling shutter: seconds from the first row's capture to the last row's (0: global shutter).
  // Keypoints are then moved to the middle row's instant (map/rolling_shutter.h).
  double readout_time = 0.0;
  std::string name = "custom";

  bool has_distortion() const;
  // Throws ConfigError naming the value if any is impossible or implausible: a non-finite or
  // non-positive focal length, depth factor or size, a side below kMinCameraSide, a principal
  // point outside the image, a focal length outside [kMinFocalPerSide, kMaxFocalPerSide] x side.
  void validate() const;

  // Undistorted normalized/pixel conversions.
  Eigen::Vector2d project(const Eigen::Vector3d& p_cam) const {
    return {fx * p_cam.x() / p_cam.z() + cx, fy * p_cam.y() / p_cam.z() + cy};
  }
  Eigen::Vector3d unproject(double u, double v, double depth) const {
    return {(u - cx) / fx * depth, (v - cy) / fy * depth, depth};
  }
  bool in_image(double u, double v, double border = 0.0) const {
    return u >= border && v >= border && u < width - border && v < height - border;
  }
  // Metric depth from a raw 16-bit depth value (0 = no measurement -> 0).
  double depth_from_raw(std::uint16_t raw) const {
    return raw == 0 ? 0.0 : raw / depth_factor * depth_scale_correction;
  }

  // Applies the distortion model to an undistorted pixel (for rendering / tests).
  Eigen::Vector2d distort_pixel(const Eigen::Vector2d& undistorted) const;
  // Removes distortion from pixel coordinates (iterative, OpenCV-compatible). In-place on xy pairs.
  void undistort_pixels(std::vector<Eigen::Vector2d>& pixels) const;
  Eigen::Vector2d undistort_pixel(const Eigen::Vector2d& distorted) const;

  // Bounds of the undistorted image (min_u, max_u, min_v, max_v), used to lay out feature grids.
  std::array<double, 4> undistorted_bounds() const;
};

// True if a and b project alike: the same intrinsics, distortion and size (depth scaling, readout
// time and name aside).
bool same_projection(const PinholeCamera& a, const PinholeCamera& b);

// Presets for the TUM RGB-D cameras (colour camera, as published with the benchmark).
PinholeCamera camera_tum_fr1();
PinholeCamera camera_tum_fr2(bool depth_correction = false);
PinholeCamera camera_tum_fr3();
// "tum1" | "tum2" | "tum2-corrected" | "tum3" | "synthetic" -> preset; throws ConfigError otherwise.
PinholeCamera camera_preset(const std::string& name);

}  // namespace cslam
