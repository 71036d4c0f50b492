// Feature test: OpenCV ORB (1000 features) finds >= 500 keypoints spread over the image
// (>= 10 of 16 cells of a 4x4 grid) on >= 95% of demo-preset frames (every 5th frame, rendered
// in-process). Also checks the depth range the tracker sees and that robots share places.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "support/synth/renderer.h"
#include "support/synth/synth_config.h"
#include "support/synth/trajectory_planner.h"

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
      for (const auto& k : kps)
        cells[std::min(3, static_cast<int>(k.pt.y * 4 / gray.rows)) * 4 +
              std::min(3, static_cast<int>(k.pt.x * 4 / gray.cols))] = true;
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
  std::printf(
      "ORB: %d/%d frames with >= 500 well-spread keypoints (min %d); depth in 0.8-4 m: %.1f%% of valid pixels\n", good,
      frames, min_kp, 100.0 * in_range / valid);
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
  const int same =
      orb_matches(view_of(ra, repeated, p.face_a, p.center_a).bgr, view_of(ra, repeated, p.face_b, p.center_b).bgr);
  const int different =
      orb_matches(view_of(rp, plain, p.face_a, p.center_a).bgr, view_of(rp, plain, p.face_b, p.center_b).bgr);
  std::printf("ORB matches between the two patch views: %d with --repeat-texture, %d without\n", same, different);
  EXPECT_GT(same, 150);
  EXPECT_LT(different, 40);
}

TEST(SynthFeatures, DemoRobotsSeeEachOthersPlaces) {
  // Map fusion needs views of the same places: robot 2's frames against robot 1's (the loop robot,
  // looking the same way from the room centre) and against robot 3's (same path, shifted).
  const SynthConfig c = synth_preset("demo");
  const Scene scene = make_scene(c.scene);
  const TrajectoryPlan plan = plan_trajectories(scene, c.trajectory);
  const Renderer renderer(scene, c.camera);
  auto closest_view = [](const Trajectory& t, const SE3& T) {
    size_t best = 0;
    double best_cost = 1e9;
    for (size_t i = 0; i < t.size(); ++i) {
      const double cost = (t[i].T_world_cam.inverse() * T).rotation_angle() +
                          0.3 * (t[i].T_world_cam.translation() - T.translation()).norm();
      if (cost < best_cost) {
        best_cost = cost;
        best = i;
      }
    }
    return best;
  };
  const Trajectory &r1 = plan.robots[0].trajectory, &r2 = plan.robots[1].trajectory, &r3 = plan.robots[2].trajectory;
  int with_r1 = 0, with_r3 = 0;
  const int samples = 6;
  for (int k = 0; k < samples; ++k) {
    const SE3& T2 = r2[30 + k * 45].T_world_cam;
    const cv::Mat img2 = renderer.render(T2).bgr;
    const int m1 = orb_matches(img2, renderer.render(r1[closest_view(r1, T2)].T_world_cam).bgr);
    const int m3 = orb_matches(img2, renderer.render(r3[closest_view(r3, T2)].T_world_cam).bgr);
    std::printf("robot 2 frame %d: %d ORB matches with robot 1, %d with robot 3\n", 30 + k * 45, m1, m3);
    with_r1 += m1 >= 30;
    with_r3 += m3 >= 30;
  }
  EXPECT_GE(with_r1, samples - 1);
  EXPECT_GE(with_r3, 2);  // robot 3 retraces the last part of robot 2's path only
}
