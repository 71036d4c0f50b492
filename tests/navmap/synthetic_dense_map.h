#pragma once
// Test fixture: the synthetic room rendered along a robot's path and integrated with the
// ground-truth poses into TSDF submaps (windows of frames, each volume in its first frame's
// camera frame). The SLAM world is the first camera's frame, as in cslam (no gravity): the scene
// (z up, floor at z = 0) is at T_scene_world from it.
#include <memory>
#include <string>
#include <vector>

#include "dense/tsdf_volume.h"
#include "navmap/submap_view.h"
#include "support/synth/renderer.h"
#include "support/synth/synth_config.h"
#include "support/synth/trajectory_planner.h"

namespace cslam::test {

struct DenseFixtureOptions {
  std::string preset = "test-small";  // scene of this preset
  int width = 160, height = 120;      // render size
  int robots = 1, frames = 300;       // trajectory (robot 1 drives the loop when loop)
  bool loop = true;
  int every = 10;  // integrate every n-th frame of each robot
  int window = 6;  // integrated frames per submap
  float voxel = 0.02f, truncation = 0.06f;
  double max_depth = 6.0;
};

struct DenseFixture {
  synth::Scene scene;
  SE3 T_scene_world;                                 // world = the first camera's frame
  std::vector<std::unique_ptr<TsdfVolume>> volumes;  // owned
  SubmapViews views;                                 // into volumes, T_world_submap
  std::vector<SE3> T_world_cams;                     // every integrated frame
  std::size_t frames_integrated = 0;
};

inline DenseFixture make_dense_fixture(const DenseFixtureOptions& o) {
  synth::SynthConfig sc = synth::synth_preset(o.preset);
  sc.trajectory.robots = o.robots;
  sc.trajectory.frames = o.frames;
  sc.trajectory.loop = o.loop;
  const PinholeCamera cam = synth::synthetic_camera(o.width, o.height);
  DenseFixture f;
  f.scene = synth::make_scene(sc.scene);
  const synth::TrajectoryPlan plan = synth::plan_trajectories(f.scene, sc.trajectory);
  synth::RenderOptions ro = sc.render;
  ro.max_depth = o.max_depth;
  const synth::Renderer renderer(f.scene, cam, ro);
  const RayTable rays(cam);
  TsdfConfig tc;
  tc.voxel_size = o.voxel;
  tc.truncation = o.truncation;
  tc.stride = 1;
  f.T_scene_world = plan.robots.front().trajectory.front().T_world_cam;
  const SE3 T_world_scene = f.T_scene_world.inverse();
  for (const synth::RobotPlan& robot : plan.robots) {
    SE3 T_scene_submap;
    int in_window = o.window;
    for (std::size_t k = 0; k < robot.trajectory.size(); k += std::size_t(o.every)) {
      const SE3& T_scene_cam = robot.trajectory[k].T_world_cam;
      if (in_window == o.window) {
        f.volumes.push_back(std::make_unique<TsdfVolume>(tc));
        T_scene_submap = T_scene_cam;
        f.views.push_back({f.volumes.back().get(), T_world_scene * T_scene_submap});
        in_window = 0;
      }
      const synth::RenderedFrame img = renderer.render(T_scene_cam);
      f.volumes.back()->integrate(img.bgr, img.depth, rays, T_scene_submap.inverse() * T_scene_cam, 0.3, o.max_depth);
      f.T_world_cams.push_back(T_world_scene * T_scene_cam);
      ++f.frames_integrated;
      ++in_window;
    }
  }
  return f;
}

}  // namespace cslam::test
