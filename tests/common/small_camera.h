#pragma once
// The small pinhole camera of the dense tests (160 x 120, f = 100 px, TUM depth factor) and a
// fronto-parallel plane seen by it: hand-made RGB-D frames with a known surface.
#include <cmath>

#include <opencv2/core.hpp>

#include "geometry/camera.h"

namespace cslam::test {

inline PinholeCamera small_camera() {
  PinholeCamera c;
  c.fx = c.fy = 100;
  c.cx = 79.5;
  c.cy = 59.5;
  c.width = 160;
  c.height = 120;
  c.depth_factor = 5000;
  return c;
}

// BGR (40, 80, 120) everywhere, every pixel at depth_m.
inline cv::Mat plane_colour(const PinholeCamera& c) {
  return cv::Mat(c.height, c.width, CV_8UC3, cv::Scalar(40, 80, 120));
}
inline cv::Mat plane_depth(const PinholeCamera& c, double depth_m) {
  return cv::Mat(c.height, c.width, CV_16UC1, cv::Scalar(std::round(depth_m * c.depth_factor)));
}

}  // namespace cslam::test
