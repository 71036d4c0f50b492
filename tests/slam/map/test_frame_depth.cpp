// Keypoint depth when the depth image was captured at another instant than the colour image:
// depth_at_keypoint reads it where the point along the keypoint's ray lay in the depth image.
#include <cmath>
#include <cstdint>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "geometry/camera.h"
#include "geometry/se3.h"
#include "slam/map/frame_data.h"

using namespace cslam;

namespace {

// A slanted plane n . X = d (world = colour camera at the colour image's instant).
struct Plane {
  Eigen::Vector3d n = Eigen::Vector3d(0.6, -0.5, -1.0).normalized();
  double d = -1.2;
  // Depth (z in camera c) along the ray through undistorted pixel `px` of a camera with pose T_world_c.
  double depth_along(const PinholeCamera& cam, const Eigen::Vector2d& px, const SE3& T_world_c) const {
    const Eigen::Vector3d ray((px.x() - cam.cx) / cam.fx, (px.y() - cam.cy) / cam.fy, 1.0);
    const Eigen::Vector3d o = T_world_c.translation(), dir = T_world_c.rotation() * ray;
    const double s = (d - n.dot(o)) / n.dot(dir);
    return s;  // the ray's z component is 1, so the ray parameter is the depth
  }
};

// The registered depth image a camera at pose T_world_depthcam measures of the plane (raw units).
cv::Mat render_depth(const PinholeCamera& cam, const Plane& plane, const SE3& T_world_depthcam) {
  cv::Mat depth(cam.height, cam.width, CV_16UC1);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const double z = plane.depth_along(cam, cam.undistort_pixel(Eigen::Vector2d(x, y)), T_world_depthcam);
      depth.at<std::uint16_t>(y, x) = std::uint16_t(std::lround(z * cam.depth_factor));
    }
  return depth;
}

}  // namespace

TEST(FrameDepth, ReadsDepthWhereTheCameraMotionCarriedThePoint) {
  const PinholeCamera cam = camera_tum_fr1();  // with lens distortion: the lookup must distort
  RgbdParams rgbd;
  rgbd.depth_time_compensation = true;
  const Plane plane;
  // The depth image is taken 15 ms after the colour image while the camera turns at 90 deg/s and
  // moves at 0.5 m/s: 1.35 deg and 7.5 mm, about 12 px at the image centre.
  const SE3 T_world_depthcam(
      Eigen::Quaterniond(Eigen::AngleAxisd(1.35 * M_PI / 180, Eigen::Vector3d(0.3, 1.0, 0.1).normalized())),
      Eigen::Vector3d(0.0075, 0.001, 0.0));
  const SE3 T_depthcam_cam = T_world_depthcam.inverse();
  const cv::Mat depth = render_depth(cam, plane, T_world_depthcam);
  double worst_compensated = 0, sum_in_place = 0;
  int n = 0;
  for (int y = 80; y < 420; y += 37)
    for (int x = 80; x < 560; x += 41) {
      const Eigen::Vector2d distorted(x, y), undistorted = cam.undistort_pixel(distorted);
      const double truth = plane.depth_along(cam, undistorted, SE3());
      const double compensated = depth_at_keypoint(depth, distorted, undistorted, cam, rgbd, T_depthcam_cam);
      const double in_place = depth_at_keypoint(depth, distorted, undistorted, cam, rgbd, std::nullopt);
      ASSERT_GT(compensated, 0) << x << "," << y;
      ASSERT_GT(in_place, 0) << x << "," << y;
      worst_compensated = std::max(worst_compensated, std::abs(compensated - truth) / truth);
      sum_in_place += std::abs(in_place - truth) / truth;
      ++n;
    }
  // Left: pixel rounding on the slanted plane (measured 0.12 % at worst); read in place, the depth
  // belongs to the surface point ~12 px away (measured 2.1 % on average).
  EXPECT_LT(worst_compensated, 0.003);
  EXPECT_GT(sum_in_place / n, 0.008);
}

TEST(FrameDepth, NoMotionOrCompensationOffReadsInPlace) {
  const PinholeCamera cam = camera_tum_fr1();
  RgbdParams rgbd;
  rgbd.depth_time_compensation = true;
  const cv::Mat depth =
      render_depth(cam, Plane(),
                   SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY())), Eigen::Vector3d::Zero()));
  const SE3 motion(Eigen::Quaterniond(Eigen::AngleAxisd(-0.02, Eigen::Vector3d::UnitY())), Eigen::Vector3d::Zero());
  for (int y = 100; y < 400; y += 50)
    for (int x = 100; x < 540; x += 60) {
      const Eigen::Vector2d distorted(x, y), undistorted = cam.undistort_pixel(distorted);
      const double in_place = depth_at_keypoint(depth, distorted, undistorted, cam, rgbd, std::nullopt);
      // Identity motion: the same pixel, the same value.
      EXPECT_NEAR(depth_at_keypoint(depth, distorted, undistorted, cam, rgbd, SE3()), in_place, 2e-4) << x << "," << y;
      rgbd.depth_time_compensation = false;
      EXPECT_EQ(depth_at_keypoint(depth, distorted, undistorted, cam, rgbd, motion), in_place);
      rgbd.depth_time_compensation = true;
    }
}

TEST(FrameDepth, PointCarriedOutOfTheDepthImageHasNoDepth) {
  const PinholeCamera cam = camera_tum_fr1();
  RgbdParams rgbd;
  rgbd.depth_time_compensation = true;
  const cv::Mat depth = render_depth(cam, Plane(), SE3());
  // A large turn to the side: keypoints near the left edge land outside the depth image.
  const SE3 motion(Eigen::Quaterniond(Eigen::AngleAxisd(-0.3, Eigen::Vector3d::UnitY())), Eigen::Vector3d::Zero());
  const Eigen::Vector2d distorted(20, 240);
  EXPECT_GT(depth_at_keypoint(depth, distorted, cam.undistort_pixel(distorted), cam, rgbd, std::nullopt), 0);
  EXPECT_EQ(depth_at_keypoint(depth, distorted, cam.undistort_pixel(distorted), cam, rgbd, motion), 0);
}
