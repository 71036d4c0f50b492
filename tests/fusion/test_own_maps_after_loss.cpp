// A robot whose camera goes blind for longer than max_lost_seconds starts a new map; when it sees
// the old map's places again, map fusion joins its two maps, and its trajectory then covers the
// frames of both, in one frame, on the ground truth. Stepped system: deterministic.
#include <gtest/gtest.h>

#include "common/run_program.h"
#include "eval/trajectory_eval.h"
#include "geometry/camera_io.h"
#include "io/tum_dataset.h"
#include "system/collaborative_system.h"
#include "io/dataset_frame.h"

using namespace cslam;

namespace {

struct Blackout {
  Trajectory groundtruth;  // the replayed sequence's ground truth at its own (shifted) stamps
  std::vector<RgbdFrame> frames;
  std::size_t before = 0, after = 0;  // real frames before and after the blind stretch
};

// Frames 0..39 of the robot, 12 frames with a covered lens (black, no depth), then the robot
// "comes back": frames 10..119 again, stamped after the blind stretch.
Blackout make_blackout(const TumDataset& ds, ClientId id) {
  Blackout b;
  const double period = ds.pairs[1].rgb_time - ds.pairs[0].rgb_time;
  auto gt_at = [&](double t) {
    for (const auto& p : *ds.groundtruth)
      if (std::abs(p.timestamp - t) < 1e-6) return p.T_world_cam;
    ADD_FAILURE() << "no ground truth at " << t;
    return SE3();
  };
  std::uint64_t seq = 0;
  double t = 0;
  for (std::size_t i = 0; i < 40; ++i, ++b.before) {
    b.frames.push_back(load_dataset_frame(ds.pairs[i], id, seq++));
    t = ds.pairs[i].rgb_time;
    b.groundtruth.push_back({t, gt_at(t)});
  }
  for (int k = 0; k < 12; ++k) {
    RgbdFrame black = load_dataset_frame(ds.pairs[40], id, seq++);
    black.bgr.setTo(cv::Scalar(0, 0, 0));
    black.depth.setTo(0);
    t += period;
    black.timestamp = t;
    b.frames.push_back(std::move(black));
  }
  const double shift = t + period - ds.pairs[10].rgb_time;
  for (std::size_t i = 10; i < ds.pairs.size(); ++i, ++b.after) {
    RgbdFrame f = load_dataset_frame(ds.pairs[i], id, seq++);
    f.timestamp = ds.pairs[i].rgb_time + shift;
    b.groundtruth.push_back({f.timestamp, gt_at(ds.pairs[i].rgb_time)});
    b.frames.push_back(std::move(f));
  }
  return b;
}

}  // namespace

TEST(FusionOwnMaps, MapStartedAfterALongLossIsJoinedAndTheTrajectoryCoversBoth) {
  test::TempDir dir("cslam_fusion_own_maps");
  const auto r = test::render_test_scene(dir / "scene", "--frames 120 --seed 5");
  ASSERT_EQ(r.status, 0) << r.output;
  const TumDataset ds = open_tum_dataset(dir / "scene/robot_1");
  ASSERT_TRUE(ds.groundtruth);
  const Blackout b = make_blackout(ds, 1);

  for (const bool fusion_on : {true, false}) {
    SCOPED_TRACE(fusion_on ? "fusion on" : "fusion off");
    SystemConfig config;
    config.stepped = true;
    config.slam.threaded = false;
    config.fusion.threaded = false;
    config.fusion.enabled = fusion_on;
    config.slam.max_lost_seconds = 0.2;  // the 12 blind frames (0.4 s) are a long loss here
    CollaborativeSystem system(config);
    ClientInfo info;
    info.id = 1;
    info.camera = load_camera_file(dir / "scene/robot_1/camera.yaml");
    system.add_client(info);
    for (const auto& f : b.frames) ASSERT_TRUE(system.submit(f));
    system.finish();

    const auto snap = system.snapshot();
    ASSERT_EQ(snap.clients.size(), 1u);
    ASSERT_EQ(snap.clients[0].maps, 2) << "the blind stretch must have started a second map";
    const Trajectory traj = system.trajectories().at(1);
    const auto ate = compute_ate(b.groundtruth, traj, Alignment::kSE3);
    std::printf("fusion %s: %zu fusion events, %zu poses of %zu real frames, ATE %.4f m\n", fusion_on ? "on" : "off",
                snap.events.size(), traj.size(), b.before + b.after, ate.stats.rmse);
    if (fusion_on) {
      ASSERT_GE(snap.events.size(), 1u) << "the client's two maps were never joined";
      EXPECT_EQ(snap.events[0].client_a, 1u);
      EXPECT_EQ(snap.events[0].client_b, 1u);
      // The real frames of both maps are in the trajectory, before and after the loss.
      EXPECT_GE(traj.size() + 2, b.before + b.after);
      EXPECT_LT(traj.front().timestamp, b.groundtruth[b.before - 1].timestamp) << "the first map's frames are missing";
      EXPECT_GT(traj.back().timestamp, b.groundtruth[b.before].timestamp) << "the second map's frames are missing";
      // One frame: both parts agree with one rigid alignment to the ground truth.
      EXPECT_LT(ate.stats.rmse, 0.02);
      EXPECT_EQ(ate.stats.n, int(traj.size()));
      // The snapshot counts the current map's keyframes; the written ones are both maps'.
      EXPECT_GT(system.keyframe_trajectory(1).size(), std::size_t(snap.clients[0].keyframes));
    } else {
      // Without fusion the two maps stay in two frames: only the larger one is written.
      EXPECT_TRUE(snap.events.empty());
      EXPECT_LT(traj.size(), b.before + b.after - 25);
    }
  }
}
