#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "core/error.h"
#include "geometry/camera.h"
#include "geometry/camera_io.h"

using namespace cslam;

TEST(Camera, ProjectUnprojectRoundTrip) {
  const PinholeCamera c = camera_tum_fr1();
  const Eigen::Vector3d p(0.31, -0.22, 1.7);
  const Eigen::Vector2d uv = c.project(p);
  EXPECT_LT((c.unproject(uv.x(), uv.y(), p.z()) - p).norm(), 1e-12);
  // Hand-computed: u = fx * x / z + cx.
  EXPECT_NEAR(uv.x(), 517.306408 * 0.31 / 1.7 + 318.643040, 1e-9);
}

TEST(Camera, DistortUndistortRoundTrip) {
  const PinholeCamera c = camera_tum_fr1();
  for (double u : {20.0, 160.0, 320.0, 600.0})
    for (double v : {15.0, 240.0, 470.0}) {
      const Eigen::Vector2d d = c.distort_pixel({u, v});
      const Eigen::Vector2d back = c.undistort_pixel(d);
      EXPECT_LT((back - Eigen::Vector2d(u, v)).norm(), 0.05) << u << "," << v;
    }
  const auto b = c.undistorted_bounds();
  EXPECT_LT(b[0], b[1]);
  EXPECT_LT(b[2], b[3]);
}

TEST(Camera, PresetsAndValidation) {
  EXPECT_NEAR(camera_preset("tum2-corrected").depth_scale_correction, 1.031, 1e-12);
  EXPECT_THROW(camera_preset("nope"), ConfigError);
  PinholeCamera bad = camera_tum_fr3();
  bad.fx = -1;
  EXPECT_THROW(bad.validate(), ConfigError);
  EXPECT_NEAR(camera_tum_fr1().depth_from_raw(5000), 1.0, 1e-12);
  EXPECT_EQ(camera_tum_fr1().depth_from_raw(0), 0.0);
  // The TUM Kinect/Xtion colour cameras are rolling shutter; the synthetic renderer is not.
  for (const char* name : {"tum1", "tum2", "tum2-corrected", "tum3"})
    EXPECT_DOUBLE_EQ(camera_preset(name).readout_time, 0.020);
  EXPECT_EQ(camera_preset("synthetic").readout_time, 0.0);
  EXPECT_EQ(PinholeCamera().readout_time, 0.0);
  for (double readout : {-0.001, 1.5, std::nan("")}) {
    PinholeCamera c = camera_tum_fr1();
    c.readout_time = readout;
    EXPECT_THROW(c.validate(), ConfigError) << readout;
  }
}

TEST(Camera, FileRoundTripYamlAndJson) {
  const test::TempDir dir("cslam_cam_test");
  for (const char* ext : {".yaml", ".json"}) {
    const std::string path = dir / (std::string("camera") + ext);
    save_camera_file(camera_tum_fr1(), path);
    const PinholeCamera c = load_camera_file(path);
    EXPECT_DOUBLE_EQ(c.fx, camera_tum_fr1().fx);
    EXPECT_DOUBLE_EQ(c.dist[4], camera_tum_fr1().dist[4]);
    EXPECT_DOUBLE_EQ(c.readout_time, camera_tum_fr1().readout_time);
    EXPECT_EQ(c.width, 640);
    std::filesystem::remove(path);
  }
}

TEST(Camera, FileErrors) {
  const test::TempDir dir("cslam_cam_bad");
  const std::string path = dir / "camera.yaml";
  { std::ofstream(path) << "%YAML:1.0\nfx: 500\nfy: 500\ncx: 320\ncy: 240\nwidth: 640\nheight: 480\nfoo: 1\n"; }
  EXPECT_THROW(load_camera_file(path), InputError);  // unknown key
  { std::ofstream(path) << "%YAML:1.0\nfx: 500\nfy: 500\ncx: 320\nwidth: 640\nheight: 480\n"; }
  EXPECT_THROW(load_camera_file(path), InputError);  // missing cy
  { std::ofstream(path) << "%YAML:1.0\nfx: 500\nfy: 500\ncx: 320\ncy: 240\nwidth: 640\nheight: 480\n"; }
  EXPECT_EQ(load_camera_file(path).readout_time, 0.0);  // no readout_time key: global shutter
  {
    std::ofstream(path)
        << "%YAML:1.0\nfx: 500\nfy: 500\ncx: 320\ncy: 240\nwidth: 640\nheight: 480\nreadout_time: -0.01\n";
  }
  EXPECT_THROW(load_camera_file(path), InputError);  // negative readout
  EXPECT_THROW(load_camera_file("/nonexistent/cam.yaml"), InputError);
  std::filesystem::remove(path);
}

// Projection geometry decides whether ray tables and stored cameras can be reused: every
// intrinsic, distortion coefficient and side counts; depth scaling, readout and name do not.
TEST(Camera, SameProjectionComparesGeometryOnly) {
  const PinholeCamera a = camera_tum_fr1();
  PinholeCamera b = a;
  b.depth_factor = 1000;
  b.readout_time = 0;
  b.name = "other";
  EXPECT_TRUE(same_projection(a, b));
  auto differs = [&](auto change) {
    PinholeCamera c = a;
    change(c);
    return !same_projection(a, c) && !same_projection(c, a);
  };
  EXPECT_TRUE(differs([](PinholeCamera& c) { c.fx += 1e-9; }));
  EXPECT_TRUE(differs([](PinholeCamera& c) { c.fy += 1; }));
  EXPECT_TRUE(differs([](PinholeCamera& c) { c.cx += 1; }));
  EXPECT_TRUE(differs([](PinholeCamera& c) { c.cy += 1; }));
  for (int k = 0; k < 5; ++k) EXPECT_TRUE(differs([k](PinholeCamera& c) { c.dist[k] += 1e-6; })) << k;
  EXPECT_TRUE(differs([](PinholeCamera& c) { c.width = 320; }));
  EXPECT_TRUE(differs([](PinholeCamera& c) { c.height = 240; }));
}
