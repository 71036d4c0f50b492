// A client that stops sending (disconnects) after its map was fused keeps its part of the fused
// map: its trajectory and keyframes stay, in the group's frame, while the other client goes on
// and the group BA moves every map of the group.
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "eval/trajectory_eval.h"
#include "geometry/camera_io.h"
#include "io/tum_dataset.h"
#include "system/collaborative_system.h"

using namespace cslam;

TEST(FusionDisconnect, ClientStoppingAfterFusionKeepsItsPartOfTheFusedMap) {
  test::TempDir dir("cslam_fusion_disconnect");
  const auto r = test::render_test_scene(dir / "scene", "--frames 120 --seed 5");
  ASSERT_EQ(r.status, 0) << r.output;
  const TumDataset d1 = open_tum_dataset(dir / "scene/robot_1"), d2 = open_tum_dataset(dir / "scene/robot_2");

  std::mutex m;
  std::condition_variable cv;
  std::uint64_t done = 0;
  SystemConfig config;
  config.on_frame_done = [&](const FrameDone&) {
    std::lock_guard<std::mutex> lock(m);
    ++done;
    cv.notify_all();
  };
  CollaborativeSystem system(config);
  for (ClientId id : {1, 2}) {
    ClientInfo info;
    info.id = id;
    info.camera = load_camera_file(dir / ("scene/robot_" + std::to_string(id) + "/camera.yaml"));
    system.add_client(info);
  }
  auto submit = [&](ClientId id, const RgbdPair& p, std::uint64_t seq) {
    const auto im = load_rgbd(p);
    RgbdFrame f;
    f.client = id;
    f.seq = seq;
    f.timestamp = p.rgb_time;
    f.bgr = im.bgr;
    f.depth = im.depth;
    ASSERT_TRUE(system.submit(std::move(f)));
  };
  // Both robots stream at their sensor rate (30 Hz); robot 2 stops as soon as it is fused.
  const std::size_t n = std::min(d1.pairs.size(), d2.pairs.size());
  std::size_t stopped_after = 0;
  std::uint64_t sent = 0;
  auto next = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < n; ++i) {
    submit(1, d1.pairs[i], i);
    ++sent;
    if (!stopped_after) {
      submit(2, d2.pairs[i], i);
      ++sent;
    }
    {
      std::unique_lock<std::mutex> lock(m);
      cv.wait(lock, [&] { return done >= sent; });
    }
    if (!stopped_after && !system.snapshot().events.empty()) stopped_after = i + 1;
    next += std::chrono::milliseconds(33);
    std::this_thread::sleep_until(next);  // the sensor's frame period, not a wait for a condition
  }
  system.finish();
  ASSERT_GT(stopped_after, 0u) << "the two clients never fused";
  std::printf("client 2 stopped after %zu of %zu frames, once fused\n", stopped_after, n);
  ASSERT_LE(stopped_after + 5, n) << "fused too late for client 1 to go on alone";

  const auto groups = system.groups();
  const auto snap = system.snapshot();
  ASSERT_EQ(snap.clients.size(), 2u);
  EXPECT_EQ(snap.clients[0].group, snap.clients[1].group) << "the stopped client left the group";
  for (const auto& c : snap.clients) EXPECT_GT(c.keyframes, 0) << "client " << c.id;
  const auto trajs = system.trajectories();
  EXPECT_EQ(trajs.at(1).size(), n);
  EXPECT_EQ(trajs.at(2).size(), stopped_after);
  // Both trajectories in one frame: one alignment to ground truth fits them together.
  const auto ate = compute_ate_joint({{*d1.groundtruth, trajs.at(1)}, {*d2.groundtruth, trajs.at(2)}}, Alignment::kSE3);
  std::printf("joint ATE %.4f m\n", ate.stats.rmse);
  // Threaded run, 120 frames: fused at frame 70-79 and joint ATE 0.0084-0.0098 m over 17 repeats
  // beside other tests and a busy loop (with 60 frames the fusion came at frame 47-57 and, under
  // load, too late for client 1 to go on alone).
  EXPECT_LT(ate.stats.rmse, 0.03);
  EXPECT_GE(snap.group_ba.started, 1);
}
