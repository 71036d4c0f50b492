// Same seed -> byte-identical dataset (PNGs, lists, ground truth, scene.ply, scene.json);
// a different seed -> a different scene. Also checks the TUM layout is readable by our readers.
#include <unistd.h>

#include <algorithm>
#include <filesystem>

#include <gtest/gtest.h>

#include "geometry/camera_io.h"
#include "io/tum_dataset.h"
#include "support/synth/dataset_writer.h"
#include "support/synth/surface_sampling.h"
#include "support/synth/trajectory_planner.h"
#include "synth_test_util.h"

using namespace cslam;
using namespace cslam::synth;
using cslam::synth::test::TempDir;

namespace {

SynthConfig small_config(std::uint64_t seed, const std::string& out) {
  SynthConfig c = synth_preset("test-small");
  c.scene.seed = seed;
  c.trajectory.frames = 20;
  c.output.out_dir = out;
  c.output.ply_spacing = 0.03;  // keep the test fast; the default is 1 cm
  c.output.threads = 2;
  return c;
}

}  // namespace

TEST(SynthDeterminism, SameSeedGivesIdenticalFiles) {
  TempDir tmp;
  SynthConfig a = small_config(42, tmp / "a"), b = small_config(42, tmp / "b");
  a.render.degradation.enabled = b.render.degradation.enabled = true;  // noise must be seeded too
  b.output.threads = 1;                                                // thread count must not change the output
  generate_dataset(a);
  generate_dataset(b);
  const auto files_a = test::list_files(tmp / "a"), files_b = test::list_files(tmp / "b");
  ASSERT_EQ(files_a, files_b);
  // robot_1, robot_2: 20 rgb + 20 depth + 4 files each; scene.ply, scene.json.
  EXPECT_EQ(files_a.size(), 2u * (40 + 4) + 2);
  for (const auto& f : files_a) EXPECT_EQ(test::read_bytes(tmp / ("a/" + f)), test::read_bytes(tmp / ("b/" + f))) << f;
}

TEST(SynthDeterminism, DifferentSeedGivesDifferentScene) {
  TempDir tmp;
  generate_dataset(small_config(1, tmp / "a"));
  generate_dataset(small_config(2, tmp / "b"));
  EXPECT_NE(test::read_bytes(tmp / "a/scene.ply"), test::read_bytes(tmp / "b/scene.ply"));
  EXPECT_NE(test::read_bytes(tmp / "a/scene.json"), test::read_bytes(tmp / "b/scene.json"));
  const auto files = test::list_files(tmp / "a/robot_1/rgb");
  ASSERT_FALSE(files.empty());
  int differing = 0;
  for (const auto& f : files)
    differing += test::read_bytes(tmp / ("a/robot_1/rgb/" + f)) != test::read_bytes(tmp / ("b/robot_1/rgb/" + f));
  EXPECT_EQ(differing, static_cast<int>(files.size()));
  // Scenes differ in furniture too, not only in texture.
  const Scene sa = make_scene(small_config(1, "").scene), sb = make_scene(small_config(2, "").scene);
  ASSERT_FALSE(sa.furniture.empty());
  EXPECT_NE(sa.furniture[0].center, sb.furniture[0].center);
}

TEST(SynthDeterminism, OutputIsATumDatasetWithCameraAndCloud) {
  TempDir tmp;
  const SynthConfig c = small_config(5, tmp / "out");
  const DatasetResult r = generate_dataset(c);
  ASSERT_EQ(r.sequences.size(), 2u);
  EXPECT_EQ(r.frames, 40);
  for (int k = 1; k <= 2; ++k) {
    const std::string dir = tmp / ("out/robot_" + std::to_string(k));
    const TumDataset ds = open_tum_dataset(dir);
    ASSERT_EQ(ds.pairs.size(), 20u);
    ASSERT_TRUE(ds.groundtruth.has_value());
    ASSERT_EQ(ds.groundtruth->size(), 20u);
    EXPECT_NEAR(ds.pairs.front().rgb_time, 1000000000.0, 1e-6);
    EXPECT_NEAR(ds.pairs[1].rgb_time - ds.pairs[0].rgb_time, 1.0 / 30, 1e-6);
    EXPECT_DOUBLE_EQ(ds.pairs[3].rgb_time, ds.pairs[3].depth_time);
    EXPECT_NEAR((*ds.groundtruth)[3].timestamp, ds.pairs[3].rgb_time, 1e-6);
    const RgbdImages im = load_rgbd(ds.pairs[10]);
    EXPECT_EQ(im.bgr.cols, 320);
    EXPECT_EQ(im.depth.type(), CV_16UC1);
    EXPECT_GT(cv::countNonZero(im.depth), im.depth.total() / 2);
    const PinholeCamera cam = load_camera_file(dir + "/camera.yaml");
    EXPECT_EQ(cam.width, 320);
    EXPECT_EQ(cam.height, 240);
    EXPECT_DOUBLE_EQ(cam.depth_factor, 5000.0);
    EXPECT_FALSE(cam.has_distortion());
    EXPECT_NEAR(cam.fx, c.camera.fx, 1e-9);
  }
  const SurfacePoints cloud = read_ply(tmp / "out/scene.ply");
  EXPECT_EQ(cloud.size(), r.surface_points);
  EXPECT_GT(cloud.size(), 100000u);
  EXPECT_FALSE(std::filesystem::exists(tmp / "out.tmp-" + std::to_string(::getpid())));
}

TEST(SynthDeterminism, WholeModeWritesOneLongSequence) {
  TempDir tmp;
  SynthConfig c = small_config(3, tmp / "whole_out");
  c.output.whole = true;
  const DatasetResult r = generate_dataset(c);
  ASSERT_EQ(r.sequences.size(), 1u);
  const TumDataset ds = open_tum_dataset(tmp / "whole_out/whole");
  EXPECT_GT(ds.pairs.size(), 40u);  // both robots' paths plus the transition
  EXPECT_EQ(static_cast<int>(ds.pairs.size()), r.frames);
  EXPECT_FALSE(std::filesystem::exists(tmp / "whole_out/robot_1"));
}

TEST(SynthDeterminism, RowBandThreadsAndNoiseSeed) {
  SynthConfig c = synth_preset("test-small");
  c.render.degradation.enabled = true;
  const Scene scene = make_scene(c.scene);
  const SE3 T = plan_trajectories(scene, c.trajectory).robots[0].trajectory[20].T_world_cam;
  RenderOptions three = c.render;
  three.threads = 3;
  const Renderer r1(scene, c.camera, c.render), r3(scene, c.camera, three);
  const RenderedFrame a = r1.render(T, 11), b = r3.render(T, 11), other = r1.render(T, 12);
  EXPECT_EQ(cv::norm(a.bgr, b.bgr, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.depth, b.depth, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a.bgr, other.bgr, cv::NORM_INF), 0.0);  // another noise seed, other noise
  EXPECT_GT(cv::norm(a.depth, other.depth, cv::NORM_INF), 0.0);
}
