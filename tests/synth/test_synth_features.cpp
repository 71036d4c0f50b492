// Feature test: OpenCV ORB (1000 features) finds >= 500 keypoints spread over the image
// (>= 10 of 16 cells of a 4x4 grid) on >= 95% of demo-preset frames (every 5th frame, rendered
// in-process). Also checks the depth range the tracker sees and that robots share places.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "synth/renderer.h"
#include "synth/synth_config.h"
#include "synth/trajectory_planner.h"

using namespace cslam;
using namespace cslam::synth;

TEST(SynthFeatures, OrbFindsManyWellSpreadKeypointsOnDemoFrames) {
  const SynthConfig c = synth_preset("demo");
  const Scene scene = make_scene(c.scene);
  const TrajectoryPlan plan = plan_trajectories(scene, c.trajectory);
  RenderOptions opt = c.render;
  opt.threads = 2;
  const Renderer renderer(scene, c.camera, opt);
  auto orb = cv::ORB::create(1000);
  int frames = 0, good = 0, min_kp = 100000;
  double in_range = 0, valid = 0;
  for (const auto& robot : plan.robots)
    for (size_t i = 0; i < robot.trajectory.size(); i += 5) {
      const RenderedFrame f = renderer.render(robot.trajectory[i].T_world_cam);
      cv::Mat gray;
      cv::cvtColor(f.bgr, gray, cv::COLOR_BGR2GRAY);
      std::vector<cv::KeyPoint> kps;
      orb->detect(gray, kps);
      bool cells[16] = {};
      for (const auto& k : kps) cells[std::min(3, static_cast<int>(k.pt.y * 4 / gray.rows)) * 4 + std::min(3, static_cast<int>(k.pt.x * 4 / gray.cols))] = true;
      const int occupied = static_cast<int>(std::count(cells, cells + 16, true));
      ++frames;
      good += kps.size() >= 500 && occupied >= 10;
      min_kp = std::min(min_kp, static_cast<int>(kps.size()));
      for (int v = 0; v < f.depth.rows; v += 4)
        for (int u = 0; u < f.depth.cols; u += 4) {
          const double z = f.depth.at<std::uint16_t>(v, u) / 5000.0;
          if (z <= 0) continue;
          valid += 1;
          in_range += z >= 0.8 && z <= 4.0;
        }
    }
  std::printf("ORB: %d/%d frames with >= 500 well-spread keypoints (min %d); depth in 0.8-4 m: %.1f%% of valid pixels\n", good, frames,
              min_kp, 100.0 * in_range / valid);
  ASSERT_GT(frames, 150);
  EXPECT_GE(good, static_cast<int>(std::ceil(0.95 * frames)));
  EXPECT_GT(in_range / valid, 0.7);
}
