// Pose feedback over real sockets (loopback) with the SLAM running: a live client streams a
// synthetic sequence to a deliberately slow worker. Every frame sent is acknowledged once; the
// worker skips stale live frames; each tracked frame's Ack carries exactly the server's
// trajectory pose for that frame; lost frames carry no pose; and the server's trajectory holds
// exactly the frames acknowledged as tracked.
#include <atomic>
#include <map>
#include <mutex>
#include <set>

#include <gtest/gtest.h>

#include "client/frame_sender.h"
#include "common/run_program.h"
#include "geometry/camera_io.h"
#include "io/tum_dataset.h"
#include "net_test_util.h"

namespace cslam {
namespace {

TEST(PoseFeedback, AcksCarryTheServersTrajectoryPosesWhileASlowLiveWorkerSkipsFrames) {
  test::TempDir dir("cslam_pose_feedback");
  const std::string data = test::render_small_scene(dir / "scene");
  const TumDataset dataset = open_tum_dataset(data);
  ASSERT_GE(dataset.pairs.size(), 50u);

  server::ReceiverConfig rc;
  rc.window = 4;
  SystemConfig sc;
  sc.client_queue_capacity = 8;
  sc.slam.threaded = false;  // mapping inside process(): the trajectory only changes on the worker
  std::atomic<test::InProcessServer*> server{nullptr};
  std::atomic<bool> client_done{false}, worker_blocked{false};
  std::mutex mutex;
  std::map<std::uint64_t, FrameDone> reported;         // seq -> what the worker reported
  std::map<std::uint64_t, StampedPose> trajectory_at;  // seq -> server trajectory entry at that moment
  int processed = 0;
  sc.on_frame_done = [&](const FrameDone& d) {
    CollaborativeSystem& system = server.load()->system();
    if (d.fate == FrameFate::kTracked) {
      const Trajectory trajectory = system.trajectories().at(d.client);
      for (const auto& p : trajectory)
        if (p.timestamp == d.timestamp) {
          std::lock_guard<std::mutex> lock(mutex);
          trajectory_at[d.seq] = p;
        }
    }
    {
      std::lock_guard<std::mutex> lock(mutex);
      reported[d.seq] = d;
      if (d.fate == FrameFate::kSkipped || ++processed % 5 != 0) return;
    }
    // Every 5th processed frame the worker falls behind until frames pile up in its queue.
    worker_blocked = true;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!client_done && std::chrono::steady_clock::now() < deadline) {
      const auto snap = system.snapshot();
      if (!snap.clients.empty() && snap.clients[0].queue_depth >= 2) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    worker_blocked = false;
  };
  test::InProcessServer srv(rc, sc);
  server = &srv;

  client::SenderConfig cc;
  cc.server = srv.endpoint();
  cc.info.id = 1;
  cc.info.name = "robot1";
  cc.info.camera = load_camera_file(data + "/camera.yaml");
  cc.reply_timeout_s = 120;
  client::FrameSender sender(cc);
  std::vector<wire::PoseFeedback> feedback;
  sender.set_pose_callback([&](const wire::PoseFeedback& f) { feedback.push_back(f); });
  std::vector<wire::RgbdFrame> frames;
  for (const auto& pair : dataset.pairs) {
    RgbdImages images = load_rgbd(pair);
    RgbdFrame f;
    f.timestamp = pair.rgb_time;
    f.bgr = images.bgr;
    f.depth = images.depth;
    frames.push_back(sender.encode(f));
  }
  sender.connect();
  for (auto& frame : frames) {
    // Keep pace with the worker (small motion between processed frames) except while it is
    // behind: then frames arrive faster than it consumes them.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!worker_blocked && sender.in_flight() > 1 && std::chrono::steady_clock::now() < deadline)
      sender.service_until(std::chrono::steady_clock::now() + std::chrono::milliseconds(2));
    sender.offer_encoded(std::move(frame), std::chrono::steady_clock::now());
  }
  client_done = true;
  ASSERT_TRUE(sender.goodbye(120));
  srv.stop();
  srv.system().finish();

  // Every frame sent was acknowledged exactly once, in order, with what the worker reported.
  ASSERT_EQ(feedback.size(), sender.stats().frames_sent);
  ASSERT_EQ(reported.size(), feedback.size());
  std::size_t skipped = 0, tracked = 0;
  std::set<double> tracked_stamps;
  for (std::size_t i = 0; i < feedback.size(); ++i) {
    const wire::PoseFeedback& f = feedback[i];
    if (i > 0) {
      EXPECT_GT(f.seq, feedback[i - 1].seq);
    }
    ASSERT_TRUE(reported.count(f.seq));
    const FrameDone& d = reported.at(f.seq);
    EXPECT_EQ(f.fate, d.fate) << "seq " << f.seq;
    EXPECT_EQ(f.timestamp, d.timestamp);
    EXPECT_EQ(f.group, d.group);
    EXPECT_EQ(f.map, d.map);
    EXPECT_EQ(f.map_epoch, d.map_epoch);
    skipped += f.fate == FrameFate::kSkipped;
    if (f.fate != FrameFate::kTracked) {
      EXPECT_FALSE(f.has_pose) << "seq " << f.seq << " (" << to_string(f.fate) << ") carries a pose";
      continue;
    }
    ++tracked;
    ASSERT_TRUE(f.has_pose);
    tracked_stamps.insert(f.timestamp);
    // The Ack's pose is the server's trajectory pose of that frame when it was acknowledged.
    ASSERT_TRUE(trajectory_at.count(f.seq)) << "seq " << f.seq << " tracked but not in the trajectory";
    const SE3& want = trajectory_at.at(f.seq).T_world_cam;
    EXPECT_LT((f.T_world_cam.translation() - want.translation()).norm(), 1e-9) << "seq " << f.seq;
    EXPECT_LT(f.T_world_cam.rotation().angularDistance(want.rotation()), 1e-9) << "seq " << f.seq;
  }
  EXPECT_GT(skipped, 0u);
  // Enough tracked frames to compare poses. How many frames track after the (timing-dependent)
  // skips is a tracking-robustness figure measured by scripts/bench-capacity.sh, not asserted here:
  // on a loaded machine the client drops more frames and the gaps grow.
  EXPECT_GE(tracked, 3u);
  const auto snap = srv.system().snapshot();
  EXPECT_EQ(snap.clients.at(0).frames_skipped, skipped);
  EXPECT_EQ(feedback.back().frames_skipped, skipped);
  // The trajectory is complete for the frames processed: exactly the frames acked as tracked.
  std::set<double> final_stamps;
  const Trajectory final_trajectory = srv.system().trajectories().at(1);
  for (const auto& p : final_trajectory) final_stamps.insert(p.timestamp);
  EXPECT_EQ(final_stamps, tracked_stamps);
}

}  // namespace
}  // namespace cslam
