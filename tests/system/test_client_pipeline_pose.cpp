// A frame that becomes a keyframe is acknowledged as soon as its pose is final, before the frame's
// processing ends (ClientSlam::set_early_pose_listener): once per frame, with the pose the
// server's trajectory holds for it at that moment.
#include <condition_variable>
#include <map>
#include <mutex>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "geometry/camera_io.h"
#include "io/dataset_frame.h"
#include "io/tum_dataset.h"
#include "system/collaborative_system.h"

using namespace cslam;

TEST(ClientPipelinePose, AKeyframesFrameIsAcknowledgedBeforeItsProcessingEnds) {
  test::TempDir dir("cslam_pipeline_pose");
  const auto r = test::render_test_scene(dir / "scene", "--frames 60 --seed 5");
  ASSERT_EQ(r.status, 0) << r.output;
  const TumDataset ds = open_tum_dataset(dir / "scene/robot_1");
  ASSERT_GE(ds.pairs.size(), 60u);

  SystemConfig sc;
  sc.slam.threaded = false;  // local mapping inline on the worker: one outcome
  sc.fusion.threaded = false;
  std::mutex mutex;
  std::condition_variable cv;
  std::map<std::uint64_t, int> acks;  // seq -> Acks
  std::size_t early = 0, tracked = 0;
  double worst_gap = 0;
  CollaborativeSystem* system_ptr = nullptr;
  sc.on_frame_done = [&](const FrameDone& d) {
    CollaborativeSystem& system = *system_ptr;
    // Counted as processed only at the frame's end: an Ack before it is an early one.
    const bool before_end = system.snapshot().clients.at(0).frames_processed == d.seq;
    double gap = -1;
    if (d.fate == FrameFate::kTracked) {
      const Trajectory trajectory = system.trajectories().at(d.client);
      for (const auto& p : trajectory)
        if (p.timestamp == d.timestamp)
          gap = (p.T_world_cam.translation() - d.T_world_cam.translation()).norm() +
                p.T_world_cam.rotation().angularDistance(d.T_world_cam.rotation());
    }
    std::lock_guard<std::mutex> lock(mutex);
    ++acks[d.seq];
    if (d.fate == FrameFate::kTracked) {
      ++tracked;
      worst_gap = gap < 0 ? 1e9 : std::max(worst_gap, gap);
    }
    early += before_end ? 1 : 0;
    cv.notify_all();
  };
  CollaborativeSystem system(sc);
  system_ptr = &system;
  ClientInfo info;
  info.id = 1;
  info.camera = load_camera_file(dir / "scene/robot_1/camera.yaml");
  system.add_client(info);
  for (std::size_t i = 0; i < 60; ++i) {
    ASSERT_TRUE(system.submit(load_dataset_frame(ds.pairs[i], info.id, i)));
    std::unique_lock<std::mutex> lock(mutex);
    ASSERT_TRUE(cv.wait_for(lock, std::chrono::seconds(120), [&] { return acks.size() == i + 1; })) << i;
  }
  // The frame's end sends nothing more: one Ack per frame.
  system.finish();
  ASSERT_EQ(acks.size(), 60u);
  for (const auto& [seq, n] : acks) EXPECT_EQ(n, 1) << "seq " << seq;
  EXPECT_EQ(tracked, 60u);
  EXPECT_LT(worst_gap, 1e-9);
  const int keyframes = system.snapshot().clients.at(0).keyframes;
  EXPECT_GE(keyframes, 3);
  EXPECT_GE(early, 2u);  // every keyframe after the map's first
}
