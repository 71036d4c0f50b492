// Trajectory validity: inside the room, clear of furniture, within the per-frame limits, smooth;
// robots share places (same place, same viewing direction); the loop returns to its start.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "support/synth/synth_config.h"
#include "support/synth/trajectory_planner.h"

using namespace cslam;
using namespace cslam::synth;

namespace {

constexpr double kDeg = 3.14159265358979 / 180.0;

// Number of poses of b within 0.25 m horizontally, 0.5 m vertically (robots differ in height)
// and 15 degrees of some pose of a.
int shared_poses(const Trajectory& a, const Trajectory& b) {
  int n = 0;
  for (const auto& pb : b)
    for (const auto& pa : a)
      if ((pa.T_world_cam.translation() - pb.T_world_cam.translation()).head<2>().norm() < 0.25 &&
          std::abs(pa.T_world_cam.translation().z() - pb.T_world_cam.translation().z()) < 0.5 &&
          (pa.T_world_cam.inverse() * pb.T_world_cam).rotation_angle() < 15 * kDeg) {
        ++n;
        break;
      }
  return n;
}

void expect_valid(const Scene& scene, const Trajectory& t, const TrajectoryConfig& cfg, const std::string& what) {
  const TrajectoryCheck c = check_trajectory(scene, t, cfg);
  EXPECT_TRUE(c.ok) << what << ": " << c.problem;
  EXPECT_LE(c.max_step, cfg.max_step) << what;
  EXPECT_LE(c.max_rotation_deg, cfg.max_rotation_deg) << what;
  EXPECT_LT(c.max_acceleration, 1.5) << what;  // m/s^2: smooth starts, stops and turns
  EXPECT_GE(c.min_height, cfg.min_height) << what;
  EXPECT_LE(c.max_height, cfg.max_height) << what;
  EXPECT_GT(c.min_furniture_distance, 0.5) << what;
  EXPECT_GT(c.min_wall_distance, 1.0) << what;
  for (const auto& p : t) EXPECT_TRUE(scene.is_free(p.T_world_cam.translation())) << what;
  for (size_t i = 1; i < t.size(); ++i) EXPECT_NEAR(t[i].timestamp - t[i - 1].timestamp, 1.0 / cfg.rate_hz, 1e-6);
}

}  // namespace

TEST(SynthTrajectory, DemoPlanIsValidSharedAndLooped) {
  const SynthConfig c = synth_preset("demo");
  const Scene scene = make_scene(c.scene);
  const TrajectoryPlan plan = plan_trajectories(scene, c.trajectory);
  ASSERT_EQ(plan.robots.size(), 3u);
  for (size_t k = 0; k < plan.robots.size(); ++k) {
    const Trajectory& t = plan.robots[k].trajectory;
    const TrajectoryCheck s = check_trajectory(scene, t, c.trajectory);
    std::printf(
        "robot %zu (%s): max %.1f mm and %.2f deg per frame, max accel %.2f m/s^2, >= %.2f m from furniture, height "
        "%.2f-%.2f m\n",
        k + 1, plan.robots[k].kind.c_str(), s.max_step * 1e3, s.max_rotation_deg, s.max_acceleration,
        s.min_furniture_distance, s.min_height, s.max_height);
    ASSERT_EQ(t.size(), 300u);
    EXPECT_DOUBLE_EQ(t.front().timestamp, 1000000000.0);
    expect_valid(scene, t, c.trajectory, "robot " + std::to_string(k + 1));
  }
  // Robot 1 closes a loop: ends where it started, looking the same way, after a full turn.
  const Trajectory& loop = plan.robots[0].trajectory;
  EXPECT_EQ(plan.robots[0].kind, "loop");
  EXPECT_LT((loop.front().T_world_cam.translation() - loop.back().T_world_cam.translation()).norm(), 0.01);
  EXPECT_LT((loop.front().T_world_cam.inverse() * loop.back().T_world_cam).rotation_angle(), 1 * kDeg);
  EXPECT_LT((loop.front().T_world_cam.translation() - loop[150].T_world_cam.translation()).norm(), 2.5);
  EXPECT_GT((loop.front().T_world_cam.inverse() * loop[150].T_world_cam).rotation_angle(), 150 * kDeg);
  // Robots 2 and 3 pass through the same places facing the same way (overlap 0.35 of the path).
  const int shared = shared_poses(plan.robots[1].trajectory, plan.robots[2].trajectory);
  std::printf("robot 3 poses at robot 2's places: %d of 300\n", shared);
  EXPECT_GT(shared, 60);
  EXPECT_LT(shared, 200);
}

TEST(SynthTrajectory, OverlapOptionControlsSharedPlaces) {
  SynthConfig c = synth_preset("test-small");
  const Scene scene = make_scene(c.scene);
  c.trajectory.overlap = 0.0;
  const TrajectoryPlan none = plan_trajectories(scene, c.trajectory);
  c.trajectory.overlap = 0.6;
  const TrajectoryPlan much = plan_trajectories(scene, c.trajectory);
  const int shared_none = shared_poses(none.robots[0].trajectory, none.robots[1].trajectory);
  const int shared_much = shared_poses(much.robots[0].trajectory, much.robots[1].trajectory);
  EXPECT_GT(shared_much, shared_none + 15);
  for (const auto& r : much.robots) expect_valid(scene, r.trajectory, c.trajectory, "test-small robot");
}

TEST(SynthTrajectory, WholeSequenceVisitsAllPathsSmoothly) {
  const SynthConfig c = synth_preset("test-small");
  const Scene scene = make_scene(c.scene);
  const TrajectoryPlan plan = plan_trajectories(scene, c.trajectory);
  const Trajectory whole = make_whole_sequence(plan, c.trajectory);
  ASSERT_GT(whole.size(), 120u);
  expect_valid(scene, whole, c.trajectory, "whole");
  // Starts on robot 1's path and ends on robot 2's.
  EXPECT_LT(
      (whole.front().T_world_cam.translation() - plan.robots[0].trajectory.front().T_world_cam.translation()).norm(),
      1e-9);
  EXPECT_LT(
      (whole.back().T_world_cam.translation() - plan.robots[1].trajectory.back().T_world_cam.translation()).norm(),
      1e-9);
}

TEST(SynthTrajectory, SingleRobotLoopAndManyRobots) {
  SynthConfig c = synth_preset("demo");
  const Scene scene = make_scene(c.scene);
  c.trajectory.robots = 1;
  const TrajectoryPlan single = plan_trajectories(scene, c.trajectory);
  ASSERT_EQ(single.robots.size(), 1u);
  EXPECT_EQ(single.robots[0].kind, "loop");
  c.trajectory.robots = 6;
  c.trajectory.frames = 120;
  c.trajectory.loop = false;
  const TrajectoryPlan many = plan_trajectories(scene, c.trajectory);
  ASSERT_EQ(many.robots.size(), 6u);
  for (const auto& r : many.robots) expect_valid(scene, r.trajectory, c.trajectory, "one of 6 robots");
}

TEST(SynthTrajectory, CheckerCatchesViolations) {
  const SynthConfig c = synth_preset("test-small");
  const Scene scene = make_scene(c.scene);
  Trajectory t = plan_trajectories(scene, c.trajectory).robots[0].trajectory;
  ASSERT_TRUE(check_trajectory(scene, t, c.trajectory).ok);
  Trajectory jump = t;
  jump[30].T_world_cam =
      SE3(jump[30].T_world_cam.rotation(), jump[30].T_world_cam.translation() + Eigen::Vector3d(0.05, 0, 0));
  EXPECT_FALSE(check_trajectory(scene, jump, c.trajectory).ok);
  Trajectory into_furniture = t;
  const auto& f = scene.furniture.at(0);
  into_furniture[10].T_world_cam =
      SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(f.center.x(), f.center.y(), 1.0));
  const TrajectoryCheck bad = check_trajectory(scene, into_furniture, c.trajectory);
  EXPECT_FALSE(bad.ok);
  EXPECT_FALSE(bad.problem.empty());
}
