// The server's receiving loop in-process: every bad input is answered and counted, the credit
// window is enforced, and a client that vanished resumes its session with the same id.
#include <future>

#include <gtest/gtest.h>

#include "client/frame_sender.h"
#include "net_test_util.h"

namespace cslam {
namespace {

using test::small_camera;

// Reads replies until an error arrives (acks may interleave); returns its code.
wire::ErrorCode next_error(test::RawPeer& peer, std::uint32_t* credits = nullptr) {
  for (int i = 0; i < 20; ++i) {
    const auto reply = peer.receive();
    if (!reply) return wire::ERROR_UNSPECIFIED;
    if (reply->has_error()) {
      if (credits) *credits = reply->error().credits();
      return reply->error().code();
    }
  }
  return wire::ERROR_UNSPECIFIED;
}

TEST(Receiver, EveryBadInputIsAnsweredCountedAndTheServerKeepsServing) {
  server::ReceiverConfig rc;
  rc.max_message_bytes = 200000;
  SystemConfig sc;
  sc.run_slam = false;
  test::InProcessServer srv(rc, sc);
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  test::RawPeer bad(ctx, srv.endpoint());

  bad.send_bytes("\x13\x37 random bytes \xff\xfe");
  EXPECT_EQ(next_error(bad), wire::ERROR_MALFORMED);
  bad.send(test::make_frame(7, 1, 0.0, cam));
  EXPECT_EQ(next_error(bad), wire::ERROR_NOT_REGISTERED);

  bad.send(test::make_hello(7, cam));
  auto welcome = bad.receive();
  ASSERT_TRUE(welcome && welcome->has_welcome());
  EXPECT_EQ(welcome->welcome().credits(), rc.window);
  EXPECT_FALSE(welcome->welcome().resumed());

  const std::string full = test::make_frame(7, 1, 0.0, cam).SerializeAsString();
  bad.send_bytes(full.substr(0, full.size() / 2));
  EXPECT_EQ(next_error(bad), wire::ERROR_MALFORMED);

  wire::ClientMessage m = test::make_frame(7, 1, 0.0, cam);
  m.mutable_frame()->mutable_rgb()->set_encoding(wire::Encoding(77));
  bad.send(m);
  std::uint32_t credits = 0;
  EXPECT_EQ(next_error(bad, &credits), wire::ERROR_UNKNOWN_ENCODING);
  EXPECT_EQ(credits, 1u);  // a dropped frame hands its credit back

  PinholeCamera other = cam;
  other.width = 80;
  bad.send(test::make_frame(7, 1, 0.0, other));
  EXPECT_EQ(next_error(bad), wire::ERROR_SIZE_MISMATCH);

  m = test::make_frame(7, 1, 0.0, cam);
  m.mutable_frame()->mutable_rgb()->set_data(m.frame().rgb().data().substr(0, 20) + std::string(50, 'x'));
  bad.send(m);
  EXPECT_EQ(next_error(bad), wire::ERROR_CORRUPT_IMAGE);
  CodecOptions png;
  png.rgb = RgbCodec::kPng;
  png.depth = DepthCodec::kPng;
  m = test::make_frame(7, 1, 0.0, cam, png);
  std::string depth_png = m.frame().depth().data();
  depth_png[depth_png.size() / 2] ^= 0x55;
  depth_png[depth_png.size() / 2 + 1] ^= 0x55;
  m.mutable_frame()->mutable_depth()->set_data(depth_png.substr(0, depth_png.size() - 12));
  bad.send(m);
  EXPECT_EQ(next_error(bad), wire::ERROR_CORRUPT_IMAGE);

  bad.send(test::make_frame(7, 5, 0.5, cam));  // accepted
  bad.send(test::make_frame(7, 5, 0.5, cam));  // duplicate
  EXPECT_EQ(next_error(bad), wire::ERROR_DUPLICATE_SEQ);
  bad.send(test::make_frame(7, 3, 0.3, cam));  // out of order
  EXPECT_EQ(next_error(bad), wire::ERROR_DUPLICATE_SEQ);
  bad.send(test::make_frame(8, 6, 0.6, cam));  // claims another client
  EXPECT_EQ(next_error(bad), wire::ERROR_WRONG_CLIENT);

  // Over ZMQ_MAXMSGSIZE: ZeroMQ drops the connection, nothing reaches the application.
  wire::ClientMessage huge = test::make_frame(7, 9, 0.9, cam);
  huge.mutable_frame()->mutable_rgb()->set_data(std::string(300000, 'z'));
  bad.send(huge);
  for (auto r = bad.receive(300); r; r = bad.receive(300)) EXPECT_FALSE(r->has_error());

  // The server still serves a well-behaved peer.
  test::RawPeer good(ctx, srv.endpoint());
  good.send(test::make_hello(9, cam));
  welcome = good.receive();
  ASSERT_TRUE(welcome && welcome->has_welcome());
  good.send(test::make_frame(9, 1, 1.0, cam));
  auto ack = good.receive();
  ASSERT_TRUE(ack && ack->has_ack());
  EXPECT_EQ(ack->ack().seq(), 1u);
  EXPECT_EQ(ack->ack().credits(), 1u);

  srv.stop();
  const auto& stats = srv.stats();
  EXPECT_EQ(stats.unattributed().at("malformed"), 1u);
  EXPECT_EQ(stats.unattributed().at("not_registered"), 1u);
  const auto& c7 = stats.clients().at(7);
  EXPECT_EQ(c7.frames_accepted, 1u);
  EXPECT_EQ(c7.dropped.at("malformed"), 1u);
  EXPECT_EQ(c7.dropped.at("unknown_encoding"), 1u);
  EXPECT_EQ(c7.dropped.at("size_mismatch"), 1u);
  EXPECT_EQ(c7.dropped.at("corrupt_image"), 2u);
  EXPECT_EQ(c7.dropped.at("duplicate_seq"), 2u);
  EXPECT_EQ(c7.dropped.at("wrong_client"), 1u);
  EXPECT_GE(stats.transport().at("disconnected"), 1u);
  EXPECT_EQ(stats.clients().at(9).frames_accepted, 1u);
}

TEST(Receiver, CreditWindowIsEnforcedWhileTheWorkerIsBusy) {
  std::promise<void> gate;
  std::shared_future<void> open = gate.get_future().share();
  server::ReceiverConfig rc;
  rc.window = 3;
  SystemConfig sc;
  sc.run_slam = false;
  sc.client_queue_capacity = 3;
  sc.on_frame_done = [open](const FrameDone&) { open.wait(); };  // a stalled SLAM worker
  test::InProcessServer srv(rc, sc);
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  test::RawPeer peer(ctx, srv.endpoint());
  peer.send(test::make_hello(1, cam));
  auto welcome = peer.receive();
  ASSERT_TRUE(welcome && welcome->has_welcome());
  ASSERT_EQ(welcome->welcome().credits(), 3u);
  // A client that ignores its credits: 3 frames fit the window, the other 2 are refused at once
  // (the receiving thread never blocks on a full queue).
  for (std::uint64_t seq = 1; seq <= 5; ++seq) peer.send(test::make_frame(1, seq, double(seq), cam));
  EXPECT_EQ(next_error(peer), wire::ERROR_NO_CREDIT);
  EXPECT_EQ(next_error(peer), wire::ERROR_NO_CREDIT);
  EXPECT_FALSE(peer.receive(200).has_value());  // no ack while the worker is stalled
  gate.set_value();
  std::uint32_t credits = 0;
  for (int i = 0; i < 3; ++i) {
    auto ack = peer.receive();
    ASSERT_TRUE(ack && ack->has_ack());
    credits += ack->ack().credits();
  }
  EXPECT_EQ(credits, 3u);
  srv.stop();
  EXPECT_EQ(srv.stats().clients().at(1).frames_accepted, 3u);
  EXPECT_EQ(srv.stats().clients().at(1).dropped.at("no_credit"), 2u);
}

TEST(Receiver, VanishedClientIsMarkedDisconnectedAndResumesWithTheSameId) {
  server::ReceiverConfig rc;
  rc.heartbeat_timeout_s = 0.3;
  rc.exit_when_done = true;
  rc.expected_clients = 1;
  SystemConfig sc;
  sc.run_slam = false;
  test::InProcessServer srv(rc, sc);
  client::SenderConfig cc;
  cc.server = srv.endpoint();
  cc.info.id = 5;
  cc.info.camera = small_camera();
  cc.reply_timeout_s = 5;
  RgbdFrame frame;
  frame.bgr = cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3));
  frame.depth = cv::Mat(48, 64, CV_16UC1, cv::Scalar(3000));
  {
    client::FrameSender first(cc);
    first.connect();
    for (int i = 0; i < 3; ++i) {
      frame.timestamp = i;
      first.send_frame(frame);
      EXPECT_LE(first.in_flight(), first.window());
    }
    first.keep_alive(0.2);  // let the acks arrive, then vanish without goodbye
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(900));  // > heartbeat timeout
  client::FrameSender second(cc);
  second.connect();
  EXPECT_EQ(second.last_seq(), 3u);  // the session continues after the last accepted frame
  for (int i = 3; i < 5; ++i) {
    frame.timestamp = i;
    second.send_frame(frame);
  }
  EXPECT_TRUE(second.goodbye(10));
  ASSERT_TRUE(srv.wait_done(10));
  srv.system().finish();
  EXPECT_EQ(srv.system().trajectories().at(5).size(), 5u);
  const auto& c5 = srv.stats().clients().at(5);
  EXPECT_EQ(c5.timeouts, 1u);
  EXPECT_EQ(c5.reconnects, 1u);
  EXPECT_EQ(c5.frames_accepted, 5u);
  EXPECT_EQ(c5.dropped_total(), 0u);
}

}  // namespace
}  // namespace cslam
