// Back-projection against hand-computed points (pinhole and distorted camera).
#include <cmath>

#include <gtest/gtest.h>

#include "dense/backproject.h"

using namespace cslam;

namespace {

PinholeCamera simple_camera() {
  PinholeCamera c;
  c.fx = 500;
  c.fy = 400;
  c.cx = 320;
  c.cy = 240;
  c.width = 640;
  c.height = 480;
  c.depth_factor = 5000;
  return c;
}

}  // namespace

TEST(Backproject, HandComputedPointWithPose) {
  const PinholeCamera cam = simple_camera();
  cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(0));
  cv::Mat bgr(480, 640, CV_8UC3, cv::Scalar(0, 0, 0));
  depth.at<std::uint16_t>(100, 400) = 10000;   // 2 m at u = 400, v = 100
  bgr.at<cv::Vec3b>(100, 400) = {11, 22, 33};  // B G R
  // Camera rotated 90 degrees about z, at (1, 2, 3).
  const SE3 T_world_cam(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())),
                        Eigen::Vector3d(1, 2, 3));
  const RayTable rays(cam);
  ColoredCloud out;
  BackprojectParams p;
  ASSERT_EQ(backproject(bgr, depth, rays, T_world_cam, p, out), 1u);
  // p_cam = ((400-320)/500*2, (100-240)/400*2, 2) = (0.32, -0.7, 2); Rz(90): (x, y) -> (-y, x).
  EXPECT_NEAR(out.points[0].x(), 1 + 0.7, 1e-5);
  EXPECT_NEAR(out.points[0].y(), 2 + 0.32, 1e-5);
  EXPECT_NEAR(out.points[0].z(), 3 + 2, 1e-5);
  EXPECT_EQ(out.colors[0], (Rgb8{33, 22, 11}));
}

TEST(Backproject, DepthRangeAndStride) {
  const PinholeCamera cam = simple_camera();
  cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(5000));  // 1 m everywhere
  depth.at<std::uint16_t>(0, 0) = 1000;                 // 0.2 m: too near
  depth.at<std::uint16_t>(0, 2) = 30000;                // 6 m: too far
  cv::Mat bgr(480, 640, CV_8UC3, cv::Scalar(1, 2, 3));
  const RayTable rays(cam);
  ColoredCloud out;
  BackprojectParams p;
  p.stride = 2;
  EXPECT_EQ(backproject(bgr, depth, rays, SE3(), p, out), 320u * 240u - 2u);
  for (const auto& q : out.points) EXPECT_FLOAT_EQ(q.z(), 1.0f);
}

TEST(Backproject, DistortedCameraUsesUndistortedRays) {
  PinholeCamera cam = camera_tum_fr1();
  const RayTable rays(cam);
  // For several pixels, the ray re-distorted through the camera model lands on the pixel
  // (OpenCV's iterative undistortion leaves < 0.1 px at fr1's extreme corners).
  for (const auto& uv :
       {Eigen::Vector2i(0, 0), Eigen::Vector2i(639, 479), Eigen::Vector2i(320, 240), Eigen::Vector2i(50, 400)}) {
    const float* r = rays.ray(uv.x(), uv.y());
    const Eigen::Vector2d undist(cam.fx * r[0] + cam.cx, cam.fy * r[1] + cam.cy);
    const Eigen::Vector2d back = cam.distort_pixel(undist);
    EXPECT_NEAR(back.x(), uv.x(), 0.15);
    EXPECT_NEAR(back.y(), uv.y(), 0.15);
  }
  // fr1's distortion pushes the corners outwards (radial factor > 1 there): undistorted rays
  // of corner pixels lie inside the pinhole rays of the same pixels.
  EXPECT_GT(rays.ray(0, 0)[0], (0 - cam.cx) / cam.fx);
  EXPECT_LT(rays.ray(639, 479)[1], (479 - cam.cy) / cam.fy);
  EXPECT_GT(rays.max_radius2(), 0.0f);
}
