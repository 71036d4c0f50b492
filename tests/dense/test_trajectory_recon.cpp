// Poses from several clients, unordered, matched to a TUM-layout dataset by timestamp;
// poses without an image and unreadable images are counted; in-memory frames work the same.
#include <filesystem>
#include <fstream>
#include <tuple>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "common/run_program.h"
#include "core/error.h"
#include "dense/trajectory_recon.h"

using namespace cslam;
namespace fs = std::filesystem;

namespace {

PinholeCamera tiny_camera() {
  PinholeCamera c;
  c.fx = c.fy = 40;
  c.cx = 31.5;
  c.cy = 23.5;
  c.width = 64;
  c.height = 48;
  return c;
}

// Writes N frames (plane at 1 m) at t = 10 + 0.1 i; frame `broken` gets an unreadable depth file.
std::string make_dataset(int n, int broken) {
  static const test::TempDir dir("cslam_dense_ds");  // removed at exit
  const fs::path root = dir.str();
  fs::remove_all(root);
  fs::create_directories(root / "rgb");
  fs::create_directories(root / "depth");
  std::ofstream rgb(root / "rgb.txt"), depth(root / "depth.txt");
  rgb << "# timestamp filename\n";
  for (int i = 0; i < n; ++i) {
    const double t = 10 + 0.1 * i;
    const std::string name = std::to_string(i) + ".png";
    cv::imwrite((root / "rgb" / name).string(), cv::Mat(48, 64, CV_8UC3, cv::Scalar(10, 20, 30 + i)));
    if (i == broken)
      std::ofstream(root / "depth" / name) << "not a png";
    else
      cv::imwrite((root / "depth" / name).string(), cv::Mat(48, 64, CV_16UC1, cv::Scalar(5000)));
    rgb << std::fixed << t << " rgb/" << name << "\n";
    depth << std::fixed << t + 0.005 << " depth/" << name << "\n";
  }
  return root.string();
}

}  // namespace

TEST(MatchPosesToFrames, UnorderedPosesOneToOne) {
  Trajectory poses;
  for (double t : {3.0, 1.01, 2.0, 7.0, 1.0}) poses.push_back({t, SE3()});
  const PoseFrameMatch m = match_poses_to_frames(poses, {1.0, 2.0, 3.0}, 0.02);
  ASSERT_EQ(m.matches.size(), 3u);
  EXPECT_EQ(m.unmatched_poses, 2);  // 7.0 has no frame; 1.01 loses frame 0 to the exact 1.0
  EXPECT_DOUBLE_EQ(m.matches[0].first.timestamp, 1.0);
  EXPECT_EQ(m.matches[2].second, 2);
}

TEST(ReconstructFromTrajectories, TwoClientsUnorderedWithGapsAndBrokenImage) {
  const std::string dir = make_dataset(10, 7);
  // Client A: frames 0-5, client B: frames 4-9 (the overlap is used once), shuffled, plus a
  // pose at a time with no image.
  Trajectory poses;
  for (int i : {5, 0, 3, 1, 2, 4}) poses.push_back({10 + 0.1 * i + 0.003, SE3()});
  for (int i : {9, 4, 6, 8, 7, 5})
    poses.push_back({10 + 0.1 * i - 0.004, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01, 0, 0))});
  poses.push_back({55.0, SE3()});
  DatasetPoses src{dir, poses, tiny_camera()};
  for (int threads : {1, 2}) {
    DenseConfig cfg;
    cfg.threads = threads;
    cfg.stride = 1;
    int calls = 0, last_done = 0;
    const DenseResult r = reconstruct_from_trajectories({src}, cfg, [&](const DenseProgress& p) {
      ++calls;
      EXPECT_EQ(p.total, 10);
      EXPECT_EQ(p.done, last_done + 1);
      last_done = p.done;
    });
    EXPECT_EQ(calls, 10);
    EXPECT_EQ(r.counts.used, 9);
    EXPECT_EQ(r.counts.bad_image, 1);  // the broken depth file
    EXPECT_EQ(r.counts.no_image, 3);   // 2 duplicate overlap poses + the pose at 55 s
    ASSERT_FALSE(r.cloud.empty());
    for (const auto& p : r.cloud.points) EXPECT_NEAR(p.z(), 1.0, 1e-4);
  }
}

TEST(ReconstructFromTrajectories, MissingDatasetIsAnInputError) {
  DatasetPoses src{"/nonexistent/cslam_dataset", {{1.0, SE3()}}, tiny_camera()};
  EXPECT_THROW(reconstruct_from_trajectories({src}, DenseConfig{}), InputError);
}

TEST(ReconstructFromFrames, InMemoryFramesMatchedByTimestamp) {
  std::vector<TimedRgbd> frames;
  for (int i : {2, 0, 1})
    frames.push_back(
        {1.0 * i, 0.0, cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3)), cv::Mat(48, 64, CV_16UC1, cv::Scalar(2500))});
  FramePoses src;
  src.frames = &frames;
  src.camera = tiny_camera();
  src.poses = {{1.0, SE3()}, {0.0, SE3()}, {5.0, SE3()}};
  const DenseResult r = reconstruct_from_frames({src}, DenseConfig{});
  EXPECT_EQ(r.counts.used, 2);
  EXPECT_EQ(r.counts.no_image, 1);
  for (const auto& p : r.cloud.points) EXPECT_NEAR(p.z(), 0.5, 1e-4);
}

// The depth image taken 50 ms after the colour image while the camera moves 0.8 m/s along x:
// it is placed 4 cm further on (the trajectory interpolated at its own time), and each point
// takes its colour where it projects in the colour image, so the colour edge of the scene stays
// where the colour camera saw it.
TEST(ReconstructFromFrames, DepthImageTakenLaterIsPlacedAtItsOwnTime) {
  cv::Mat bgr(48, 64, CV_8UC3, cv::Scalar(0, 0, 255));                                           // red left half ...
  bgr(cv::Rect(32, 0, 32, 48)).setTo(cv::Scalar(255, 0, 0));                                     // ... blue right half
  std::vector<TimedRgbd> frames{{0.0, 0.05, bgr, cv::Mat(48, 64, CV_16UC1, cv::Scalar(2500))}};  // plane at 0.5 m
  FramePoses src;
  src.frames = &frames;
  src.camera = tiny_camera();
  src.poses = {{0.0, SE3()}, {0.1, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.08, 0, 0))}};
  auto mean_x_and_colour = [&](bool compensate) {
    DenseConfig cfg;
    cfg.threads = 1;
    cfg.depth_time_compensation = compensate;
    const DenseResult r = reconstruct_from_frames({src}, cfg);
    EXPECT_EQ(r.counts.used, 1);
    double x = 0;
    int blue = 0, red = 0;
    for (size_t i = 0; i < r.cloud.size(); ++i) {
      x += r.cloud.points[i].x();
      // The colour camera sees the edge at x = 0.5 * 0.5 / 40 = 6 mm: right of it is blue.
      if (r.cloud.points[i].x() > 0.015 && r.cloud.points[i].x() < 0.035)
        (r.cloud.colors[i][2] > 200 ? blue : red) += 1;
    }
    return std::tuple{x / double(r.cloud.size()), blue, red};
  };
  const auto [x_on, blue_on, red_on] = mean_x_and_colour(true);
  const auto [x_off, blue_off, red_off] = mean_x_and_colour(false);
  EXPECT_NEAR(x_on - x_off, 0.04, 2e-3);
  // The edge stays at 6 mm (read at the depth pixel itself, it would move with the depth image
  // to 46 mm and these points would be red).
  EXPECT_GT(blue_on, 0);
  EXPECT_EQ(red_on, 0);
  EXPECT_GT(blue_off, 0);
  EXPECT_EQ(red_off, 0);
}
