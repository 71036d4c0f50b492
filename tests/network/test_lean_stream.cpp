// The lean stream over a real socket (counting-only workers): full frames every K-th frame,
// light frames between (packets of one H.264 stream, subsampled depth); a packet the server never
// decoded (refused before decoding) breaks the stream, the server says so (ERROR_STREAM_GAP)
// and the robot's next packet is a key packet, after which every frame is taken again. An
// adaptive robot (SenderConfig::adapt) turns lean when the server falls behind and full again
// when it keeps up.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "client/frame_sender.h"
#include "common/run_program.h"
#include "geometry/camera_io.h"
#include "io/tum_dataset.h"
#include "net_test_util.h"
#include "slam/tracking/tracker.h"

namespace cslam {
namespace {

using test::small_camera;

// A textured image that moves one pixel per frame (something for the inter coder to predict).
RgbdFrame moving_frame(int i, const PinholeCamera& cam) {
  RgbdFrame f;
  f.timestamp = 1.0 + i / 30.0;
  f.bgr = cv::Mat(cam.height, cam.width, CV_8UC3);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const int u = x + i;
      f.bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(std::uint8_t((u * 37 + y * 11) % 251), std::uint8_t((u * y) % 253),
                                            std::uint8_t((u ^ y) * 5 % 255));
    }
  f.depth = cv::Mat(cam.height, cam.width, CV_16UC1, cv::Scalar(4000));
  return f;
}

client::SenderConfig lean_config(const std::string& endpoint, ClientId id, int depth_every) {
  client::SenderConfig cc;
  cc.server = endpoint;
  cc.info.id = id;
  cc.info.name = "robot" + std::to_string(id);
  cc.info.camera = small_camera();
  cc.codecs.rgb = RgbCodec::kJpeg;
  cc.reply_timeout_s = 60;
  cc.depth_every = depth_every;
  return cc;
}

// A robot of the small synthetic scene, and a stepped SLAM server's config that records every
// frame's FrameDone by seq (under `mutex`).
struct SmallSceneSlam {
  explicit SmallSceneSlam(const std::string& name)
      : dir(name), data(test::render_small_scene(dir / "scene")), dataset(open_tum_dataset(data)) {
    sc.slam.threaded = false;
    sc.on_frame_done = [this](const FrameDone& d) {
      std::lock_guard<std::mutex> lock(mutex);
      done[d.seq] = d;
    };
  }
  test::TempDir dir;
  std::string data;
  TumDataset dataset;
  SystemConfig sc;
  std::mutex mutex;
  std::map<std::uint64_t, FrameDone> done;
};

// Sends every frame of the dataset, each once the previous one is acknowledged (so every request
// and hint in an ack is in before the next frame leaves); `sent(i)` after frame i (0-based) left.
void send_each_after_the_last_ack(client::FrameSender& sender, const TumDataset& dataset,
                                  const std::function<void(std::size_t)>& sent = {}) {
  for (std::size_t i = 0; i < dataset.pairs.size(); ++i) {
    const auto& pair = dataset.pairs[i];
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (sender.in_flight() > 0 && std::chrono::steady_clock::now() < deadline)
      sender.service_until(std::chrono::steady_clock::now() + std::chrono::milliseconds(2));
    const RgbdImages images = load_rgbd(pair);
    RgbdFrame f;
    f.timestamp = pair.rgb_time;
    f.bgr = images.bgr;
    f.depth = images.depth;
    sender.send_frame(f);
    if (sent) sent(i);
  }
}

TEST(LeanStream, LightFramesBetweenFullFramesAreAllTaken) {
  SystemConfig sc;
  sc.run_slam = false;
  std::mutex mutex;
  std::vector<FrameDone> done;
  sc.on_frame_done = [&](const FrameDone& d) {
    std::lock_guard<std::mutex> lock(mutex);
    done.push_back(d);
  };
  test::InProcessServer srv(server::ReceiverConfig{}, sc);
  client::FrameSender sender(lean_config(srv.endpoint(), 4, 4));
  sender.connect();
  for (int i = 0; i < 20; ++i) sender.send_frame(moving_frame(i, small_camera()));
  ASSERT_TRUE(sender.goodbye());
  const auto& s = sender.stats();
  EXPECT_EQ(s.acks, 20u);
  EXPECT_EQ(s.frames_refused, 0u);
  EXPECT_EQ(s.frames_light, 15u);       // full frames 0, 4, 8, 12, 16
  EXPECT_EQ(s.colour_key_packets, 1u);  // the stream's first packet
  EXPECT_EQ(s.stream_gaps, 0u);
  EXPECT_LT(double(s.bytes_light) / 15.0, double(s.bytes_sent - s.bytes_light) / 5.0);  // a light frame is smaller
  srv.stop();
  EXPECT_EQ(srv.stats().clients().at(4).frames_light, 15u);
  std::lock_guard<std::mutex> lock(mutex);
  EXPECT_EQ(done.size(), 20u);
}

TEST(LeanStream, ARobotAnswersTheServersDepthRequestWithItsNextFrame) {
  // SLAM on a synthetic scene: tracking defers a keyframe that falls due on a light frame and
  // asks for full depth in that frame's ack. The robot sends each frame once the previous one is
  // acknowledged, so every request is answered by the very next frame (lag 1).
  SmallSceneSlam scene("cslam_lean_request");
  ASSERT_GE(scene.dataset.pairs.size(), 50u);
  test::InProcessServer srv(server::ReceiverConfig{}, scene.sc);
  client::SenderConfig cc = lean_config(srv.endpoint(), 1, 5);
  cc.info.camera = load_camera_file(scene.data + "/camera.yaml");
  client::FrameSender sender(cc);
  sender.connect();
  send_each_after_the_last_ack(sender, scene.dataset);
  ASSERT_TRUE(sender.goodbye(120));
  srv.stop();
  const auto& s = sender.stats();
  EXPECT_EQ(s.frames_refused, 0u);
  ASSERT_GE(s.depth_requests, 1u) << "tracking never deferred a keyframe";
  EXPECT_GE(s.depth_requests_met + 1, s.depth_requests);  // the last frame's request may stay open
  EXPECT_EQ(s.depth_request_lag_max, 1u);
  EXPECT_EQ(s.depth_request_lag_sum, s.depth_requests_met);
  std::lock_guard<std::mutex> lock(scene.mutex);
  int asked = 0;
  for (const auto& [seq, d] : scene.done)
    if (d.wants_depth && scene.done.count(seq + 1)) ++asked;
  EXPECT_EQ(std::uint64_t(asked), s.depth_requests_met);
}

TEST(LeanStream, AnAdaptiveRobotGoesLeanWhileTheServerQueuesAndBackWhenCalm) {
  SystemConfig sc;
  sc.run_slam = false;
  std::atomic<bool> slow{false};
  // A server that falls behind: each frame costs 120 ms while `slow`, so the robot's frames queue.
  sc.on_frame_done = [&](const FrameDone&) {
    if (slow) std::this_thread::sleep_for(std::chrono::milliseconds(120));
  };
  test::InProcessServer srv(server::ReceiverConfig{}, sc);
  client::SenderConfig cc = lean_config(srv.endpoint(), 5, 1);  // configured: every frame full
  cc.adapt.enabled = true;
  cc.adapt.calm_s = 0.5;
  cc.adapt.max_depth_every = 5;  // ladder 1, 2, 3, 5
  // The slow server queues 4 frames x 120 ms; a margin of 100 ms keeps a loaded machine's jitter
  // (the test suite runs under load too) from reading as a queue in the calm phase.
  cc.adapt.margin_ms = 100;
  client::FrameSender sender(cc);
  sender.connect();
  const auto period = std::chrono::milliseconds(33);
  auto next = std::chrono::steady_clock::now();
  int i = 0;
  auto send_paced = [&] {
    next += period;
    std::this_thread::sleep_until(next);
    sender.send_frame(moving_frame(i++, small_camera()));
  };
  for (int k = 0; k < 15; ++k) send_paced();
  slow = true;
  for (int k = 0; k < 200 && sender.stats().rate_steps_down == 0; ++k) send_paced();
  ASSERT_GE(sender.stats().rate_steps_down, 1u) << "the queue never made the robot step down";
  const std::uint64_t light_before = sender.stats().frames_light;
  for (int k = 0; k < 10; ++k) send_paced();  // stepped down: light frames between full ones
  EXPECT_GT(sender.stats().frames_light, light_before);
  slow = false;
  next = std::chrono::steady_clock::now();
  for (int k = 0; k < 900 && sender.stats().depth_every > 1; ++k) send_paced();
  EXPECT_EQ(sender.stats().depth_every, 1) << "the robot did not step back up once the server kept up";
  EXPECT_GE(sender.stats().rate_steps_up, 1u);
  ASSERT_TRUE(sender.goodbye());
  const auto& s = sender.stats();
  EXPECT_EQ(s.frames_refused, 0u);
  EXPECT_EQ(s.stream_gaps, 0u);
  EXPECT_EQ(s.acks, std::uint64_t(i));
  srv.stop();
  EXPECT_EQ(srv.stats().clients().at(5).frames_light, s.frames_light);
}

TEST(LeanStream, APacketRefusedBeforeDecodingIsHealedByTheNextKeyPacket) {
  server::ReceiverConfig rc;
  rc.timestamp_bound.min_jump_s = 5.0;
  rc.timestamp_bound.wall_factor = 0.0;
  SystemConfig sc;
  sc.run_slam = false;
  test::InProcessServer srv(rc, sc);
  const PinholeCamera cam = small_camera();
  client::FrameSender sender(lean_config(srv.endpoint(), 5, 100));  // full depth only with the first frame
  sender.connect();
  for (int i = 0; i < 6; ++i) sender.send_frame(moving_frame(i, cam));
  // A wild timestamp: the receiver refuses the frame before it is decoded, so the server's colour
  // stream never sees this packet and the next one lacks its reference.
  RgbdFrame wild = moving_frame(6, cam);
  wild.timestamp += 1000.0;
  sender.send_frame(wild);
  for (int i = 7; i < 16; ++i) sender.send_frame(moving_frame(i, cam));
  EXPECT_TRUE(sender.goodbye());  // every frame answered: acked or refused
  const auto& s = sender.stats();
  EXPECT_EQ(s.errors.at("ERROR_TIMESTAMP_JUMP"), 1u);
  EXPECT_GE(s.stream_gaps, 1u);
  EXPECT_EQ(s.errors.at("ERROR_STREAM_GAP"), s.stream_gaps);
  EXPECT_EQ(s.colour_key_packets, 2u);  // the first packet, and one after the gap
  // Lossless sending keeps up to `window` frames in flight, so the gap is reported up to that
  // many frames late; every frame after the key packet is taken.
  EXPECT_EQ(s.frames_refused, 1u + s.stream_gaps);
  EXPECT_EQ(s.acks, 16u - s.frames_refused);
  EXPECT_LE(s.stream_gaps, std::uint64_t(server::ReceiverConfig{}.window));
  srv.stop();
  EXPECT_EQ(srv.stats().clients().at(5).dropped.at("stream_gap"), s.stream_gaps);  // counted on the server too
}

TEST(LeanStream, AFrameWithDepthMustCarryStandaloneColour) {
  SystemConfig sc;
  sc.run_slam = false;
  test::InProcessServer srv(server::ReceiverConfig{}, sc);
  client::FrameSender sender(lean_config(srv.endpoint(), 6, 1));
  sender.connect();
  const PinholeCamera cam = small_camera();
  video::H264Encoder encoder(cam.width, cam.height, video::H264Options{});
  // An inter-coded colour packet together with a depth image: refused, the session goes on.
  wire::RgbdFrame bad = sender.encode(moving_frame(0, cam));
  const Bytes packet = encoder.encode(moving_frame(0, cam).bgr, true);
  bad.mutable_rgb()->set_encoding(wire::RGB_H264);
  bad.mutable_rgb()->set_data(packet.data(), packet.size());
  sender.send_encoded(bad);
  sender.send_frame(moving_frame(1, cam));
  sender.goodbye();
  EXPECT_EQ(sender.stats().errors.at("ERROR_MALFORMED"), 1u);
  EXPECT_EQ(sender.stats().acks, 1u);
  srv.stop();
}

// A robot with a byte budget (SenderConfig::budget) sends the full frames' colour as the finest
// JPEG its budget leaves room for; the server takes JPEG and H.264 pictures in one stream; the
// stream stays within the budget; and a budget below what the stream sends anyway
// changes nothing, byte for byte.
TEST(LeanStream, ABudgetedRobotSpendsItsRoomOnFinerFullFrames) {
  SystemConfig sc;
  sc.run_slam = false;
  test::InProcessServer srv(server::ReceiverConfig{}, sc);
  auto run = [&](ClientId id, double bytes_per_s, std::vector<std::size_t>* sizes) {
    client::SenderConfig cc = lean_config(srv.endpoint(), id, 4);
    cc.codecs.rgb = RgbCodec::kH264Intra;
    cc.budget.bytes_per_s = bytes_per_s;
    cc.budget.frame_rate = 30;
    cc.budget.burst_s = 0.5;
    client::FrameSender sender(cc);
    sender.connect();
    for (int i = 0; i < 60; ++i) sizes->push_back(sender.send_frame(moving_frame(i, small_camera())));
    EXPECT_TRUE(sender.goodbye());
    EXPECT_EQ(sender.stats().frames_refused, 0u);
    EXPECT_EQ(sender.stats().acks, 60u);
    return sender.stats();
  };
  std::vector<std::size_t> plain, tight, roomy;
  const client::SenderStats s0 = run(7, 0, &plain);
  EXPECT_EQ(s0.frames_finer, 0u);
  const double rate = double(s0.bytes_sent) / 60.0 * 30.0;  // B/s without a budget

  const client::SenderStats s1 = run(8, 0.5 * rate, &tight);  // below the stream: no room
  EXPECT_EQ(s1.frames_finer, 0u);
  EXPECT_EQ(tight, plain);

  const double budget = 2.0 * rate;
  const client::SenderStats s2 = run(9, budget, &roomy);
  EXPECT_GT(s2.frames_finer, 0u);
  EXPECT_LE(s2.frames_finer, 15u);  // full frames only
  EXPECT_GT(s2.bytes_sent, s0.bytes_sent);
  // Within the budget but for what the light frames after the last full frame may owe.
  std::size_t light_max = 0;  // full frames: 0, 4, 8, ...
  for (std::size_t i = 0; i < roomy.size(); ++i)
    if (i % 4 != 0) light_max = std::max(light_max, roomy[i]);
  EXPECT_LE(double(s2.bytes_sent), budget * 60 / 30 + 3.0 * double(light_max));
  srv.stop();
  EXPECT_EQ(srv.stats().clients().at(9).frames_light, 45u);
}

// With SLAM every ack says when tracking expects its next keyframe (Ack::keyframe_due_in: the
// periodic rule's countdown), and a budgeted robot spends its budget on the full frames due then
// and on those answering a depth request: every full frame made finer becomes a keyframe, and
// some full frames keep the stream's own codec. The robot sends each frame once the
// previous one is acknowledged, so every hint is in before the next frame leaves.
TEST(LeanStream, ABudgetedRobotSpendsItOnTheFullFramesTrackingExpectsAsKeyframes) {
  SmallSceneSlam scene("cslam_lean_hint");
  ASSERT_GE(scene.dataset.pairs.size(), 50u);
  std::set<std::uint64_t> keyframes;
  scene.sc.on_keyframe = [&](const ClientInfo&, const KeyFrameId&, const RgbdFrame& frame, const SE3&) {
    std::lock_guard<std::mutex> lock(scene.mutex);
    keyframes.insert(frame.seq);
  };
  test::InProcessServer srv(server::ReceiverConfig{}, scene.sc);
  client::SenderConfig cc = lean_config(srv.endpoint(), 1, 5);
  cc.info.camera = load_camera_file(scene.data + "/camera.yaml");
  cc.codecs.rgb = RgbCodec::kH264Intra;
  cc.budget.bytes_per_s = 100e6;  // room for q95 on every frame it is spent on
  cc.budget.frame_rate = 30;
  client::FrameSender sender(cc);
  std::vector<int> hints;  // as the robot reads them
  sender.set_pose_callback([&](const wire::PoseFeedback& f) { hints.push_back(f.keyframe_due_in); });
  sender.connect();
  std::vector<std::uint64_t> finer;  // seqs of the full frames made finer (frame i goes as seq i + 1)
  send_each_after_the_last_ack(sender, scene.dataset, [&](std::size_t i) {
    if (sender.stats().frames_finer > finer.size()) finer.push_back(i + 1);
  });
  ASSERT_TRUE(sender.goodbye(120));
  srv.stop();
  const auto& s = sender.stats();
  EXPECT_EQ(s.frames_refused, 0u);
  std::lock_guard<std::mutex> lock(scene.mutex);
  ASSERT_EQ(scene.done.size(), scene.dataset.pairs.size());
  for (const std::uint64_t seq : finer) EXPECT_TRUE(keyframes.count(seq)) << "finer frame " << seq << " is no keyframe";
  ASSERT_EQ(hints.size(), scene.dataset.pairs.size());
  // The countdown: keyframe_every_frames (10) on a keyframe, one less every frame after, never
  // below 1 while tracking is healthy; 0 while a keyframe waits for depth.
  const int every = TrackerConfig().keyframe_every_frames;
  int counted = 0;
  for (auto it = std::next(scene.done.begin()); it != scene.done.end(); ++it) {
    const FrameDone& d = it->second;
    EXPECT_EQ(hints[d.seq - 1], d.keyframe_due_in) << "frame " << d.seq << ": the ack's hint as the robot read it";
    if (d.fate != FrameFate::kTracked) continue;
    if (d.wants_depth) {
      EXPECT_EQ(d.keyframe_due_in, 0) << "frame " << d.seq;
    } else if (keyframes.count(d.seq)) {
      EXPECT_EQ(d.keyframe_due_in, every) << "frame " << d.seq;
    } else if (const FrameDone& prev = std::prev(it)->second; prev.keyframe_due_in > 0 && !prev.wants_depth) {
      EXPECT_EQ(d.keyframe_due_in, std::max(1, prev.keyframe_due_in - 1)) << "frame " << d.seq;
      ++counted;
    }
  }
  EXPECT_GT(counted, 20);
  const std::uint64_t full = scene.dataset.pairs.size() - s.frames_light;
  EXPECT_EQ(finer.size(), s.frames_finer);
  EXPECT_GT(s.frames_finer, 2u);
  EXPECT_LT(s.frames_finer, full) << "every full frame was made finer";
}

}  // namespace
}  // namespace cslam
