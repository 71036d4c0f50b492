// Rolling-shutter compensation against a simulated rolling-shutter camera: every point is seen at
// its own row's instant; after compensation the keypoints must be where a global-shutter camera at
// the middle row's instant sees the points.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "slam/map/rolling_shutter.h"

namespace cslam {
namespace {

// The camera's motion from the middle row's instant to `tau` seconds later at a constant twist:
// points in the middle-row camera map to X_tau = R(tau) X + t(tau) (T_later_earlier).
SE3 motion(const Eigen::Vector3d& omega, const Eigen::Vector3d& vel, double tau) {
  const double angle = omega.norm() * tau;
  const Eigen::Quaterniond q(angle == 0 ? Eigen::AngleAxisd::Identity() : Eigen::AngleAxisd(angle, omega.normalized()));
  return SE3(q, vel * tau);
}

struct Scene {
  PinholeCamera cam;
  double readout = 0.03, bf = 40.0;
  Eigen::Vector3d omega, vel;
  std::vector<Eigen::Vector3d> points;  // in the middle row's camera
  OrbFeatures features;                 // as the rolling-shutter camera saw them
  std::vector<float> depth, u_right;
  double max_shift = 0;  // largest distance between seen and global-shutter pixel
};

Scene make_scene(const Eigen::Vector3d& omega, const Eigen::Vector3d& vel, bool with_depth) {
  Scene s;
  s.cam.dist = {0, 0, 0, 0, 0};
  s.omega = omega;
  s.vel = vel;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(40, 600), v(30, 450), z(0.8, 3.5);
  for (int i = 0; i < 300; ++i) {
    const double d = z(rng);
    const Eigen::Vector3d X = s.cam.unproject(u(rng), v(rng), d);
    // The row that sees X: its instant depends on the row itself (fixed point).
    double tau = 0;
    Eigen::Vector3d X_tau = X;
    Eigen::Vector2d px;
    for (int it = 0; it < 30; ++it) {
      X_tau = motion(omega, vel, tau) * X;
      px = s.cam.project(X_tau);
      tau = (px.y() - 0.5 * s.cam.height) / s.cam.height * s.readout;
    }
    if (!s.cam.in_image(px.x(), px.y())) continue;
    s.points.push_back(X);
    cv::KeyPoint kp;
    kp.pt = cv::Point2f(float(px.x()), float(px.y()));
    s.features.keypoints.push_back(kp);
    s.features.undistorted.push_back(px);
    s.depth.push_back(with_depth ? float(X_tau.z()) : -1.f);
    s.u_right.push_back(with_depth ? float(px.x() - s.bf / X_tau.z()) : -1.f);
    s.max_shift = std::max(s.max_shift, (px - s.cam.project(X)).norm());
  }
  return s;
}

double max_error(const Scene& s) {
  double e = 0;
  for (size_t i = 0; i < s.points.size(); ++i)
    e = std::max(e, (s.features.undistorted[i] - s.cam.project(s.points[i])).norm());
  return e;
}

TEST(RollingShutter, FastTurnWithDepthLandsOnTheGlobalShutterImage) {
  // 115 deg/s about a tilted axis and 0.5 m/s: fr1's fastest turns.
  Scene s = make_scene(Eigen::Vector3d(0.6, 1.7, 0.5), Eigen::Vector3d(0.3, -0.2, 0.35), true);
  ASSERT_GT(s.points.size(), 200u);
  ASSERT_GT(s.max_shift, 10.0);  // pixels the shutter moved the points
  const SE3 T_lastrow_cam = motion(s.omega, s.vel, 0.5 * s.readout);
  const int moved = compensate_rolling_shutter(s.cam, s.bf, T_lastrow_cam, s.features, s.depth, s.u_right);
  EXPECT_EQ(moved, int(s.points.size()));
  // First order in a motion of ~0.03 rad over half the readout: a few tenths of a pixel at most.
  EXPECT_LT(max_error(s), 0.3);
  for (size_t i = 0; i < s.points.size(); ++i) {
    EXPECT_NEAR(s.depth[i], s.points[i].z(), 2e-3 * s.points[i].z());
    EXPECT_NEAR(s.u_right[i], s.features.undistorted[i].x() - s.bf / s.depth[i], 1e-3);
  }
}

TEST(RollingShutter, ModerateTurnIsCompensatedToATenthOfAPixel) {
  Scene s = make_scene(Eigen::Vector3d(0.0, 0.9, 0.3), Eigen::Vector3d(0.1, 0.0, 0.1), true);
  ASSERT_GT(s.max_shift, 4.0);
  compensate_rolling_shutter(s.cam, s.bf, motion(s.omega, s.vel, 0.5 * s.readout), s.features, s.depth, s.u_right);
  EXPECT_LT(max_error(s), 0.1);
}

TEST(RollingShutter, KeypointsWithoutDepthAreCorrectedForTheRotation) {
  // Pure rotation: a ray needs no depth.
  Scene s = make_scene(Eigen::Vector3d(1.2, -0.8, 0.2), Eigen::Vector3d::Zero(), false);
  ASSERT_GT(s.max_shift, 8.0);
  compensate_rolling_shutter(s.cam, s.bf, motion(s.omega, s.vel, 0.5 * s.readout), s.features, s.depth, s.u_right);
  EXPECT_LT(max_error(s), 0.2);
  for (float d : s.depth) EXPECT_EQ(d, -1.f);  // still monocular
}

TEST(RollingShutter, TheWrongDirectionDoublesTheError) {
  // Guards the sign convention: compensating with the inverse motion makes things worse.
  Scene s = make_scene(Eigen::Vector3d(0.6, 1.7, 0.5), Eigen::Vector3d(0.3, -0.2, 0.35), true);
  const double before = max_error(s);
  compensate_rolling_shutter(s.cam, s.bf, motion(s.omega, s.vel, 0.5 * s.readout).inverse(), s.features, s.depth,
                             s.u_right);
  EXPECT_GT(max_error(s), 1.5 * before);
}

TEST(RollingShutter, NoMotionChangesNothing) {
  Scene s = make_scene(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), true);
  const auto before = s.features.undistorted;
  const auto depth_before = s.depth;
  compensate_rolling_shutter(s.cam, s.bf, SE3(), s.features, s.depth, s.u_right);
  for (size_t i = 0; i < before.size(); ++i) {
    EXPECT_NEAR((s.features.undistorted[i] - before[i]).norm(), 0.0, 1e-9);
    EXPECT_NEAR(s.depth[i], depth_before[i], 1e-6);
  }
}

}  // namespace
}  // namespace cslam
