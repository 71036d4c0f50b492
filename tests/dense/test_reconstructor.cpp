// DenseReconstructor on hand-rendered frames: a fronto-parallel plane at known depth, bad
// input counted (wrong size, all-zero depth, NaN pose), empty results, chunked filtering.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "cloud/ply_io.h"
#include "common/small_camera.h"
#include "dense/reconstructor.h"

using namespace cslam;

namespace {

using test::small_camera;

struct Frame {
  cv::Mat bgr, depth;
};
Frame plane_frame(const PinholeCamera& c, double depth_m) {
  return {test::plane_colour(c), test::plane_depth(c, depth_m)};
}

}  // namespace

TEST(DenseReconstructor, PlaneAtKnownDepth) {
  const PinholeCamera cam = small_camera();
  DenseConfig cfg;
  cfg.stride = 1;
  cfg.voxel_size = 0.01;
  cfg.chunk_frames = 2;
  for (int threads : {1, 2}) {
    cfg.threads = threads;
    DenseReconstructor recon(cfg);
    // At 0.5 m pixels are 5 mm apart: every 1 cm voxel under the footprint gets points.
    const Frame f = plane_frame(cam, 0.5);
    // Five frames sliding sideways along x: a wider plane at world z = 0.5.
    for (int i = 0; i < 5; ++i) {
      const auto o =
          recon.integrate(SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1 * i, 0, 0)), f.bgr, f.depth, cam);
      EXPECT_TRUE(o.used);
      EXPECT_EQ(o.points, size_t(cam.width * cam.height));
    }
    const DenseResult r = recon.finish();
    EXPECT_EQ(r.counts.used, 5);
    EXPECT_EQ(r.counts.skipped(), 0);
    EXPECT_EQ(r.raw_points, size_t(5 * cam.width * cam.height));
    ASSERT_FALSE(r.cloud.empty());
    const BoundingBox bb = bounding_box(r.cloud.points);
    EXPECT_NEAR(bb.min.z(), 0.5, 1e-4);
    EXPECT_NEAR(bb.max.z(), 0.5, 1e-4);
    // Footprint: x in [-79.5/100*0.5, 0.4 + 79.5/100*0.5], y in [-59.5/100*0.5, 59.5/100*0.5],
    // centroids within a voxel of the border.
    EXPECT_NEAR(bb.min.x(), -0.3975, 0.01);
    EXPECT_NEAR(bb.max.x(), 0.4 + 0.3975, 0.01);
    EXPECT_NEAR(bb.min.y(), -0.2975, 0.01);
    EXPECT_NEAR(bb.max.y(), 0.2975, 0.01);
    // Exactly one point per occupied 1 cm voxel.
    auto voxels = [](double lo, double hi) { return int(std::floor(hi / 0.01)) - int(std::floor(lo / 0.01)) + 1; };
    EXPECT_EQ(int(r.cloud.size()), voxels(-0.3975, 0.7975) * voxels(-0.2975, 0.2975));
    EXPECT_EQ(r.cloud.colors[0], (Rgb8{120, 80, 40}));
  }
}

TEST(DenseReconstructor, BadFramesAreSkippedAndCounted) {
  const PinholeCamera cam = small_camera();
  DenseConfig cfg;
  DenseReconstructor recon(cfg);
  const Frame good = plane_frame(cam, 1.0);
  const Frame zero = plane_frame(cam, 0.0);
  const Frame far = plane_frame(cam, 9.0);  // beyond max_depth
  const cv::Mat small_depth(60, 80, CV_16UC1, cv::Scalar(5000));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const SE3 bad_pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(nan, 0, 0));

  EXPECT_EQ(recon.integrate(SE3(), good.bgr, small_depth, cam).reason, SkipReason::kWrongImageSize);
  EXPECT_EQ(recon.integrate(SE3(), zero.bgr, zero.depth, cam).reason, SkipReason::kNoValidDepth);
  EXPECT_EQ(recon.integrate(SE3(), far.bgr, far.depth, cam).reason, SkipReason::kNoValidDepth);
  EXPECT_EQ(recon.integrate(bad_pose, good.bgr, good.depth, cam).reason, SkipReason::kBadPose);
  EXPECT_EQ(recon.integrate(SE3(), cv::Mat(), good.depth, cam).reason, SkipReason::kBadImage);
  cv::Mat depth_float;
  good.depth.convertTo(depth_float, CV_32F);
  EXPECT_EQ(recon.integrate(SE3(), good.bgr, depth_float, cam).reason, SkipReason::kBadImage);
  recon.count_skipped(SkipReason::kNoImage);
  EXPECT_TRUE(recon.integrate(SE3(), good.bgr, good.depth, cam).used);
  const DenseResult r = recon.finish();
  EXPECT_EQ(r.counts.used, 1);
  EXPECT_EQ(r.counts.wrong_size, 1);
  EXPECT_EQ(r.counts.no_valid_depth, 2);
  EXPECT_EQ(r.counts.bad_pose, 1);
  EXPECT_EQ(r.counts.bad_image, 2);
  EXPECT_EQ(r.counts.no_image, 1);
  EXPECT_EQ(r.counts.skipped(), 7);
  EXPECT_FALSE(r.cloud.empty());
  EXPECT_THROW(recon.finish(), std::logic_error);
}

TEST(DenseReconstructor, EmptyResultIsEmptyAndNotWritable) {
  const PinholeCamera cam = small_camera();
  DenseReconstructor recon(DenseConfig{});
  const Frame zero = plane_frame(cam, 0.0);
  recon.integrate(SE3(), zero.bgr, zero.depth, cam);
  const DenseResult r = recon.finish();
  EXPECT_TRUE(r.cloud.empty());
  EXPECT_EQ(r.counts.used, 0);
  EXPECT_THROW(write_ply("/tmp/cslam_should_not_exist.ply", r.cloud), std::invalid_argument);
}

TEST(DenseReconstructor, RejectsBadConfig) {
  DenseConfig cfg;
  cfg.max_depth = 0.1;
  EXPECT_ANY_THROW(DenseReconstructor{cfg});
  cfg = DenseConfig{};
  cfg.stride = 0;
  EXPECT_ANY_THROW(DenseReconstructor{cfg});
}

TEST(DenseReconstructor, MeshOfPlaneLiesOnPlaneAndFacesCamera) {
  const PinholeCamera cam = small_camera();
  DenseConfig cfg;
  cfg.build_mesh = true;
  cfg.tsdf.voxel_size = 0.01f;
  cfg.tsdf.truncation = 0.04f;
  DenseReconstructor recon(cfg);
  const Frame f = plane_frame(cam, 1.0);
  for (int i = 0; i < 3; ++i)
    recon.integrate(SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.02 * i, 0, 0)), f.bgr, f.depth, cam);
  const DenseResult r = recon.finish();
  EXPECT_EQ(r.counts.tsdf_frames, 3);
  ASSERT_GT(r.mesh.triangles.size(), 1000u);
  ASSERT_EQ(r.mesh.colors.size(), r.mesh.vertices.size());
  for (const auto& v : r.mesh.vertices) EXPECT_NEAR(v.z(), 1.0, 0.003);
  int facing = 0;
  for (const auto& t : r.mesh.triangles) {
    const Eigen::Vector3f n =
        (r.mesh.vertices[t[1]] - r.mesh.vertices[t[0]]).cross(r.mesh.vertices[t[2]] - r.mesh.vertices[t[0]]);
    if (n.z() < 0) ++facing;  // towards the camera (free space), which is at z = 0
  }
  EXPECT_EQ(facing, int(r.mesh.triangles.size()));
  EXPECT_EQ(r.mesh.colors[0], (Rgb8{120, 80, 40}));
  // The mesh spans the frustum footprint at 1 m.
  const BoundingBox bb = bounding_box(r.mesh.vertices);
  EXPECT_NEAR(bb.max.x() - bb.min.x(), 1.6 + 0.04, 0.05);
}
