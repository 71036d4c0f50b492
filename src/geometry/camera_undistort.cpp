// Undistortion (OpenCV's calib3d): apart from camera.cpp so that the camera model, and the
// robot library that carries it, link without calib3d.
#include <algorithm>
#include <vector>

#include <opencv2/calib3d.hpp>

#include "geometry/camera.h"

namespace cslam {

void PinholeCamera::undistort_pixels(std::vector<Eigen::Vector2d>& pixels) const {
  if (!has_distortion() || pixels.empty()) return;
  cv::Mat pts(static_cast<int>(pixels.size()), 1, CV_64FC2);
  for (size_t i = 0; i < pixels.size(); ++i) pts.at<cv::Vec2d>(static_cast<int>(i)) = {pixels[i].x(), pixels[i].y()};
  cv::Matx33d K(fx, 0, cx, 0, fy, cy, 0, 0, 1);
  cv::Mat D(1, 5, CV_64F);
  for (int i = 0; i < 5; ++i) D.at<double>(i) = dist[i];
  cv::Mat out;
  cv::undistortPoints(pts, out, K, D, cv::noArray(), K);
  for (size_t i = 0; i < pixels.size(); ++i) {
    const cv::Vec2d p = out.at<cv::Vec2d>(static_cast<int>(i));
    pixels[i] = {p[0], p[1]};
  }
}

Eigen::Vector2d PinholeCamera::undistort_pixel(const Eigen::Vector2d& distorted) const {
  std::vector<Eigen::Vector2d> one{distorted};
  undistort_pixels(one);
  return one[0];
}

std::array<double, 4> PinholeCamera::undistorted_bounds() const {
  if (!has_distortion()) return {0.0, double(width), 0.0, double(height)};
  std::vector<Eigen::Vector2d> corners{
      {0, 0}, {double(width), 0}, {0, double(height)}, {double(width), double(height)}};
  undistort_pixels(corners);
  return {std::min(corners[0].x(), corners[2].x()), std::max(corners[1].x(), corners[3].x()),
          std::min(corners[0].y(), corners[1].y()), std::max(corners[2].y(), corners[3].y())};
}

}  // namespace cslam
