// Live mode and the protocol around it, in-process over loopback (counting-only workers):
// a client without credit keeps only its newest frame, a worker that fell behind skips stale
// live frames, every frame is acknowledged once with its fate, lossless mode still loses nothing,
// an old-protocol peer gets a clear error, and a flooding client cannot starve another.
#include <future>
#include <thread>

#include <gtest/gtest.h>

#include "client/frame_sender.h"
#include "net_test_util.h"

namespace cslam {
namespace {

using test::small_camera;

RgbdFrame frame_at(double timestamp, const PinholeCamera& cam) {
  RgbdFrame f;
  f.timestamp = timestamp;
  f.bgr = cv::Mat(cam.height, cam.width, CV_8UC3, cv::Scalar(10, 20, 30));
  f.depth = cv::Mat(cam.height, cam.width, CV_16UC1, cv::Scalar(4000));
  return f;
}

// Polls the system until the client's queue holds `depth` frames (the receiving thread has
// dispatched them); false after a generous timeout.
bool wait_queue_depth(CollaborativeSystem& system, ClientId id, std::size_t depth) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline) {
    for (const auto& c : system.snapshot().clients)
      if (c.id == id && c.queue_depth >= depth) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return false;
}

client::SenderConfig sender_config(const std::string& endpoint, ClientId id) {
  client::SenderConfig cc;
  cc.server = endpoint;
  cc.info.id = id;
  cc.info.name = "robot" + std::to_string(id);
  cc.info.camera = small_camera();
  cc.codecs.rgb = RgbCodec::kRaw;
  cc.codecs.depth = DepthCodec::kRaw;
  cc.reply_timeout_s = 60;
  return cc;
}

TEST(LiveMode, NoCreditKeepsTheNewestFrameAndTheSlowWorkerSkipsStaleOnes) {
  // The worker stalls on its first frame until the test opens the gate: a deliberately slow worker.
  std::promise<void> gate;
  std::shared_future<void> open = gate.get_future().share();
  std::promise<void> first_started;
  std::atomic<bool> first{true};
  server::ReceiverConfig rc;
  rc.window = 4;
  SystemConfig sc;
  sc.run_slam = false;
  sc.client_queue_capacity = 8;
  std::mutex done_mutex;
  std::vector<FrameDone> done;
  sc.on_frame_done = [&](const FrameDone& d) {
    if (first.exchange(false)) {
      first_started.set_value();
      open.wait();
    }
    std::lock_guard<std::mutex> lock(done_mutex);
    done.push_back(d);
  };
  test::InProcessServer srv(rc, sc);
  client::FrameSender sender(sender_config(srv.endpoint(), 3));
  std::vector<wire::PoseFeedback> feedback;
  sender.set_pose_callback([&](const wire::PoseFeedback& f) { feedback.push_back(f); });
  sender.connect();
  ASSERT_EQ(sender.credits(), 4u);

  sender.offer_frame(frame_at(1.0, small_camera()));  // seq 1: sent, the worker takes it and stalls
  first_started.get_future().wait();
  for (int i = 2; i <= 10; ++i) {  // seqs 2..4 use the last credits; 5..9 are replaced; 10 waits
    sender.service_until(std::chrono::steady_clock::now());
    sender.offer_frame(frame_at(double(i), small_camera()));
  }
  EXPECT_EQ(sender.stats().frames_offered, 10u);
  EXPECT_EQ(sender.stats().frames_sent, 4u);
  EXPECT_EQ(sender.stats().frames_dropped_live, 5u);
  EXPECT_TRUE(sender.has_waiting_frame());
  ASSERT_TRUE(wait_queue_depth(srv.system(), 3, 3));           // frames 2, 3, 4 queued behind the stalled one
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // frame 4 stays queued at least this long
  gate.set_value();
  // The client reads no reply until the worker has consumed 1..4, so its waiting frame cannot
  // overtake them (deterministic skipping).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  for (;;) {
    {
      std::lock_guard<std::mutex> lock(done_mutex);
      if (done.size() >= 4 || std::chrono::steady_clock::now() > deadline) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_TRUE(sender.goodbye(60));  // the waiting frame goes out with the first returned credit
  EXPECT_EQ(sender.stats().frames_sent, 5u);
  srv.stop();
  srv.system().finish();

  // Worker: 1 processed, 2 and 3 skipped (4 was newer), 4 processed, then the client's newest.
  std::vector<std::pair<double, FrameFate>> got;
  for (const auto& f : feedback) got.emplace_back(f.timestamp, f.fate);
  const std::vector<std::pair<double, FrameFate>> want = {{1.0, FrameFate::kTracked},
                                                          {2.0, FrameFate::kSkipped},
                                                          {3.0, FrameFate::kSkipped},
                                                          {4.0, FrameFate::kTracked},
                                                          {10.0, FrameFate::kTracked}};
  EXPECT_EQ(got, want);
  for (const auto& f : feedback) {
    EXPECT_EQ(f.has_pose, f.fate == FrameFate::kTracked) << "seq " << f.seq;
    EXPECT_GE(f.latency_ms, 0.0);
  }
  EXPECT_EQ(feedback.back().frames_skipped, 2u);
  // Every consumed frame was reported once, skipped ones included.
  ASSERT_EQ(done.size(), 5u);
  for (std::size_t i = 0; i < done.size(); ++i) EXPECT_EQ(done[i].seq, feedback[i].seq);
  // The trajectory holds exactly the processed frames.
  const Trajectory traj = srv.system().trajectories().at(3);
  std::vector<double> stamps;
  for (const auto& p : traj) stamps.push_back(p.timestamp);
  EXPECT_EQ(stamps, (std::vector<double>{1.0, 4.0, 10.0}));
  const auto snap = srv.system().snapshot();
  ASSERT_EQ(snap.clients.size(), 1u);
  EXPECT_EQ(snap.clients[0].frames_skipped, 2u);
  EXPECT_EQ(snap.clients[0].frames_processed, 3u);
  EXPECT_EQ(snap.clients[0].pose_latency_samples, 3u);
  // Where the time went: frame 4 waited in the queue while frame 1 stalled; each part's p99 (here
  // the largest of 3 frames) is within the whole's, and the worker's CPU within its work.
  const auto& parts = snap.clients[0].pose_latency_parts_p99;
  EXPECT_GE(parts.queue_ms, 50.0);
  EXPECT_LE(parts.queue_ms, snap.clients[0].pose_latency_p99_ms);
  EXPECT_GE(parts.decode_ms, 0.0);
  EXPECT_EQ(parts.slot_ms, 0.0);          // no tracking slots
  EXPECT_EQ(parts.mapping_wait_ms, 0.0);  // no SLAM
  EXPECT_LE(parts.work_ms, snap.clients[0].pose_latency_p99_ms);
  EXPECT_LE(parts.work_cpu_ms, parts.work_ms + 1.0);
}

TEST(LiveMode, LosslessModeStillProcessesEveryFrameBehindASlowWorker) {
  std::promise<void> gate;
  std::shared_future<void> open = gate.get_future().share();
  std::atomic<bool> first{true};
  server::ReceiverConfig rc;
  rc.window = 4;
  SystemConfig sc;
  sc.run_slam = false;
  sc.on_frame_done = [&](const FrameDone&) {
    if (first.exchange(false)) open.wait();
  };
  test::InProcessServer srv(rc, sc);
  client::FrameSender sender(sender_config(srv.endpoint(), 4));
  std::vector<wire::PoseFeedback> feedback;
  sender.set_pose_callback([&](const wire::PoseFeedback& f) { feedback.push_back(f); });
  sender.connect();
  for (int i = 1; i <= 4; ++i) sender.send_frame(frame_at(double(i), small_camera()));
  ASSERT_TRUE(wait_queue_depth(srv.system(), 4, 3));  // lossless frames queue behind the stalled one
  gate.set_value();
  for (int i = 5; i <= 12; ++i) sender.send_frame(frame_at(double(i), small_camera()));
  ASSERT_TRUE(sender.goodbye(60));
  srv.stop();
  srv.system().finish();
  ASSERT_EQ(feedback.size(), 12u);
  for (std::size_t i = 0; i < feedback.size(); ++i) {
    EXPECT_EQ(feedback[i].seq, i + 1);
    EXPECT_EQ(feedback[i].fate, FrameFate::kTracked);
  }
  EXPECT_EQ(srv.system().trajectories().at(4).size(), 12u);
  EXPECT_EQ(srv.system().snapshot().clients[0].frames_skipped, 0u);
}

TEST(LiveMode, OldProtocolPeerGetsAClearError) {
  server::ReceiverConfig rc;
  SystemConfig sc;
  sc.run_slam = false;
  test::InProcessServer srv(rc, sc);
  zmq::context_t ctx(1);
  test::RawPeer peer(ctx, srv.endpoint());
  wire::ClientMessage hello = test::make_hello(5, small_camera());
  hello.mutable_hello()->set_version(wire::PROTOCOL_VERSION_1);
  peer.send(hello);
  const auto reply = peer.receive(10000);
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().code(), wire::ERROR_BAD_VERSION);
  const std::string text = reply->error().message();
  EXPECT_NE(text.find("protocol version 1 is not supported"), std::string::npos) << text;
  EXPECT_NE(text.find("speaks version 2"), std::string::npos) << text;
  EXPECT_NE(text.find("update the client"), std::string::npos) << text;
  // No session was opened for it; a current client is welcomed with the server's version.
  EXPECT_EQ(srv.sessions().size(), 0u);
  test::RawPeer good(ctx, srv.endpoint());
  good.send(test::make_hello(6, small_camera()));
  const auto welcome = good.receive(10000);
  ASSERT_TRUE(welcome && welcome->has_welcome());
  EXPECT_EQ(welcome->welcome().version(), wire::PROTOCOL_VERSION_2);
  srv.stop();
  EXPECT_EQ(srv.stats().unattributed().at("bad_version"), 1u);
}

TEST(LiveMode, AClientSendingFasterThanItsCreditsIsRefusedAndDoesNotStarveOthers) {
  server::ReceiverConfig rc;
  rc.window = 2;
  SystemConfig sc;
  sc.run_slam = false;
  sc.client_queue_capacity = 2;
  test::InProcessServer srv(rc, sc);
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  // The flooder ignores credits: 300 frames at once.
  test::RawPeer flooder(ctx, srv.endpoint());
  flooder.send(test::make_hello(7, cam));
  ASSERT_TRUE(flooder.receive(10000).has_value());
  for (std::uint64_t seq = 1; seq <= 300; ++seq) flooder.send(test::make_frame(7, seq, double(seq), cam));
  // A well-behaved client streams alongside and loses nothing.
  client::FrameSender good(sender_config(srv.endpoint(), 8));
  std::size_t tracked = 0;
  good.set_pose_callback([&](const wire::PoseFeedback& f) { tracked += f.fate == FrameFate::kTracked; });
  good.connect();
  for (int i = 1; i <= 40; ++i) good.send_frame(frame_at(double(i), cam));
  ASSERT_TRUE(good.goodbye(60));
  EXPECT_EQ(tracked, 40u);
  std::size_t acks = 0, errors = 0, no_credit = 0;
  // Waits for all 300 replies (each within 10 s: a loaded machine can pause the server for seconds).
  // Most refusals are for want of credit; on a loaded machine a run of more than 100 refusals also
  // makes the next accepted frame's timestamp a jump, refused as such: every refusal is counted.
  while (auto r = flooder.receive(10000)) {
    if (r->has_ack()) ++acks;
    if (r->has_error()) {
      ++errors;
      if (r->error().code() == wire::ERROR_NO_CREDIT) ++no_credit;
    }
    if (acks + errors == 300) break;
  }
  srv.stop();
  EXPECT_EQ(acks + errors, 300u);
  EXPECT_GT(no_credit, 0u);
  EXPECT_EQ(srv.stats().clients().at(7).dropped.at("no_credit"), no_credit);
  EXPECT_EQ(srv.stats().clients().at(7).dropped_total(), errors);
  EXPECT_EQ(srv.stats().clients().at(8).frames_accepted, 40u);
  EXPECT_EQ(srv.stats().clients().at(8).dropped_total(), 0u);
}

}  // namespace
}  // namespace cslam
