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

namespace {

// ORB matches (mutual nearest neighbours, Hamming < 40) between two images.
int orb_matches(const cv::Mat& a, const cv::Mat& b) {
  auto orb = cv::ORB::create(1000);
  std::vector<cv::KeyPoint> ka, kb;
  cv::Mat da, db;
  orb->detectAndCompute(a, cv::noArray(), ka, da);
  orb->detectAndCompute(b, cv::noArray(), kb, db);
  if (da.empty() || db.empty()) return 0;
  cv::BFMatcher matcher(cv::NORM_HAMMING, true);
  std::vector<cv::DMatch> m;
  matcher.match(da, db, m);
  return static_cast<int>(std::count_if(m.begin(), m.end(), [](const cv::DMatch& d) { return d.distance < 40; }));
}

// View of a wall point from 1.4 m in front of it (the walls' normals are horizontal).
RenderedFrame view_of(const Renderer& r, const Scene& scene, int face, const Eigen::Vector3d& center) {
  const Eigen::Vector3d n = scene.faces[face].normal;
  const Eigen::Vector3d eye = center + 1.4 * n;
  return r.render(camera_pose(eye, std::atan2(-n.y(), -n.x()), 0.0));
}

}  // namespace

TEST(SynthFeatures, RepeatedTexturePatchLooksAlikeAndPlacesAreOtherwiseDistinct) {
  SynthConfig c = synth_preset("demo");
  c.scene.furniture = 0;  // nothing in front of the walls
  c.scene.repeat_texture = true;
  const Scene repeated = make_scene(c.scene);
  c.scene.repeat_texture = false;
  const Scene plain = make_scene(c.scene);
  ASSERT_EQ(repeated.repeated_patches.size(), 1u);
  const RepeatedPatch& p = repeated.repeated_patches[0];
  EXPECT_GT((p.center_a - p.center_b).norm(), 2.0);  // on two different walls
  const Renderer ra(repeated, c.camera), rp(plain, c.camera);
  const int same = orb_matches(view_of(ra, repeated, p.face_a, p.center_a).bgr, view_of(ra, repeated, p.face_b, p.center_b).bgr);
  const int different = orb_matches(view_of(rp, plain, p.face_a, p.center_a).bgr, view_of(rp, plain, p.face_b, p.center_b).bgr);
  std::printf("ORB matches between the two patch views: %d with --repeat-texture, %d without\n", same, different);
  EXPECT_GT(same, 150);
  EXPECT_LT(different, 40);
}
