// A client's worker that falls behind its live frames (it skipped one) tracks the next frames as
// flow frames (FlowMode::kUnderLoad) instead of skipping more; one that keeps up never does; one
// that skips again while behind is overloaded and runs longer series of flow frames (WorkerLoad).
#include <condition_variable>
#include <future>
#include <mutex>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "eval/trajectory_eval.h"
#include "geometry/camera_io.h"
#include "io/tum_dataset.h"
#include "system/collaborative_system.h"
#include "io/dataset_frame.h"

using namespace cslam;

TEST(ClientPipelineFlow, AWorkerBehindItsLiveFramesTracksFlowFramesInsteadOfSkipping) {
  test::TempDir dir("cslam_pipeline_flow");
  const auto r = test::render_test_scene(dir / "scene", "--frames 90 --seed 5");
  ASSERT_EQ(r.status, 0) << r.output;
  const TumDataset ds = open_tum_dataset(dir / "scene/robot_1");
  ASSERT_GE(ds.pairs.size(), 90u);

  SystemConfig sc;
  sc.slam.threaded = false;  // local mapping inline on the worker: the same map run after run
  sc.fusion.threaded = false;
  sc.behind_hold_s = 3600;  // once behind, for the rest of the test (not wall-clock dependent)
  std::mutex mutex;
  std::condition_variable cv;
  std::size_t reported = 0;
  std::promise<void> gate[2], stalled[2];
  std::shared_future<void> open[2] = {gate[0].get_future().share(), gate[1].get_future().share()};
  constexpr std::uint64_t kStallAt = 30, kStallAgainAt = 60;
  sc.on_frame_done = [&](const FrameDone& d) {
    if (d.seq == kStallAt || d.seq == kStallAgainAt) {
      const int k = d.seq == kStallAt ? 0 : 1;
      stalled[k].set_value();
      open[k].wait();  // the worker holds here while frames queue up behind it
    }
    std::lock_guard<std::mutex> lock(mutex);
    ++reported;
    cv.notify_all();
  };
  auto wait_reported = [&](std::size_t n) {
    std::unique_lock<std::mutex> lock(mutex);
    return cv.wait_for(lock, std::chrono::seconds(120), [&] { return reported >= n; });
  };
  CollaborativeSystem system(sc);
  ClientInfo info;
  info.id = 1;
  info.camera = load_camera_file(dir / "scene/robot_1/camera.yaml");
  system.add_client(info);
  auto live_frame = [&](std::size_t i) {
    RgbdFrame f = load_dataset_frame(ds.pairs[i], info.id, i);
    f.live = true;
    return f;
  };

  // Keeping up: each frame waits for the previous one's result.
  for (std::size_t i = 0; i < kStallAt; ++i) {
    ASSERT_TRUE(system.submit(live_frame(i)));
    ASSERT_TRUE(wait_reported(i + 1));
  }
  EXPECT_EQ(system.snapshot().clients.at(0).frames_flow, 0u) << "a worker that keeps up tracked a flow frame";

  // Falling behind: the worker stalls on frame 30 while 31..33 arrive; 31 and 32 are skipped. Then
  // again at frame 60 (61 and 62 skipped) while still behind: overloaded.
  std::uint64_t flow_behind = 0;
  for (int k = 0; k < 2; ++k) {
    const std::size_t at = k == 0 ? kStallAt : kStallAgainAt;
    ASSERT_TRUE(system.submit(live_frame(at)));
    stalled[k].get_future().wait();
    for (std::size_t i = at + 1; i <= at + 3; ++i) ASSERT_TRUE(system.submit(live_frame(i)));
    gate[k].set_value();
    ASSERT_TRUE(wait_reported(at + 4));
    for (std::size_t i = at + 4; i < (k == 0 ? kStallAgainAt : ds.pairs.size()); ++i) {
      ASSERT_TRUE(system.submit(live_frame(i)));
      ASSERT_TRUE(wait_reported(i + 1));
    }
    if (k == 0) flow_behind = system.snapshot().clients.at(0).frames_flow;
  }
  system.finish();
  const auto c = system.snapshot().clients.at(0);
  EXPECT_EQ(c.frames_skipped, 4u);
  EXPECT_EQ(c.frames_processed, ds.pairs.size() - 4);
  const std::size_t behind = kStallAgainAt - (kStallAt + 4), overloaded = ds.pairs.size() - (kStallAgainAt + 4);
  const std::uint64_t flow_overloaded = c.frames_flow - flow_behind;
  EXPECT_GE(flow_behind, behind / 3) << "of " << behind << " frames while behind";
  // Runs of at most FlowConfig::max_run (3) flow frames while behind, max_run_overloaded (8) after.
  EXPECT_LE(4 * flow_behind, 3 * behind);
  EXPECT_GT(4 * flow_overloaded, 3 * overloaded)
      << flow_overloaded << " of " << overloaded << " frames while overloaded";
  const auto ate = compute_ate(*ds.groundtruth, system.trajectories().at(1), Alignment::kSE3);
  EXPECT_EQ(ate.stats.n, int(ds.pairs.size() - 4));  // every processed frame has a pose
  EXPECT_LT(ate.stats.rmse, 0.02);
}
