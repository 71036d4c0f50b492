// Adversarial tests of the receiving loop (loopback, in-process server): session takeover and
// sequence sanity, bounded sessions (max clients, reclaiming idle ones), camera size limits,
// drop attribution, the "disconnected" state and live counters. Each reproduces a case that the
// server got wrong before it was hardened (docs/security.md).
#include <dirent.h>

#include <filesystem>
#include <limits>

#include <gtest/gtest.h>

#include "common/process_threads.h"
#include "client/frame_sender.h"
#include "net_test_util.h"
#include "server/http/status_cache.h"

namespace cslam {
namespace {

using test::small_camera;

SystemConfig counting_system() {
  SystemConfig sc;
  sc.run_slam = false;
  return sc;
}

// Reads replies until one of the wanted kind arrives (acks may interleave).
std::optional<wire::ServerMessage> next_of(test::RawPeer& peer, wire::ServerMessage::BodyCase kind, int tries = 20,
                                           int timeout_ms = 5000) {
  for (int i = 0; i < tries; ++i) {
    auto reply = peer.receive(timeout_ms);
    if (!reply) return std::nullopt;
    if (reply->body_case() == kind) return reply;
  }
  return std::nullopt;
}

wire::ErrorCode next_error(test::RawPeer& peer) {
  const auto e = next_of(peer, wire::ServerMessage::kError);
  return e ? e->error().code() : wire::ERROR_UNSPECIFIED;
}

// Waits (generously) until the published counters satisfy pred.
template <class Pred>
std::shared_ptr<const http::NetStatus> wait_status(const test::InProcessServer& srv, Pred pred, double timeout_s = 20) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    auto s = srv.net_status();
    if (s && pred(*s)) return s;
    if (std::chrono::steady_clock::now() > deadline) return s;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

using test::thread_count;

// Case 1: another peer says hello with a live victim's id and camera, then sends seq 2^64-1.
TEST(Hardening, HelloWithALiveVictimsIdCannotTakeOverItsSession) {
  server::ReceiverConfig rc;
  test::InProcessServer srv(rc, counting_system());
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  test::RawPeer victim(ctx, srv.endpoint()), attacker(ctx, srv.endpoint());
  victim.send(test::make_hello(5, cam));
  ASSERT_TRUE(next_of(victim, wire::ServerMessage::kWelcome));
  victim.send(test::make_frame(5, 1, 0.1, cam));
  ASSERT_TRUE(next_of(victim, wire::ServerMessage::kAck));

  attacker.send(test::make_hello(5, cam));
  EXPECT_EQ(next_error(attacker), wire::ERROR_SESSION_BUSY);
  attacker.send(test::make_frame(5, std::numeric_limits<std::uint64_t>::max(), 9.9, cam));
  EXPECT_EQ(next_error(attacker), wire::ERROR_NOT_REGISTERED);

  // The victim keeps streaming with its own sequence numbers.
  for (std::uint64_t seq = 2; seq <= 4; ++seq) {
    victim.send(test::make_frame(5, seq, 0.1 * double(seq), cam));
    const auto ack = next_of(victim, wire::ServerMessage::kAck);
    ASSERT_TRUE(ack);
    EXPECT_EQ(ack->ack().seq(), seq);
  }
  srv.stop();
  srv.system().finish();
  const Trajectory t = srv.system().trajectories().at(5);
  ASSERT_EQ(t.size(), 4u);
  for (const auto& pose : t) EXPECT_LT(pose.timestamp, 1.0);   // the injected frame (t = 9.9) is not among them
  EXPECT_EQ(srv.stats().clients().at(5).dropped_total(), 0u);  // the attacker's drops are not the victim's
  EXPECT_EQ(srv.stats().unattributed().at("session_busy"), 1u);
}

// Case 1, second half: a frame whose seq jumps to 2^64-1 would lock the session out forever.
TEST(Hardening, SequenceNumbersMayNotJumpFarAhead) {
  server::ReceiverConfig rc;
  rc.max_seq_jump = 1000;
  test::InProcessServer srv(rc, counting_system());
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  test::RawPeer peer(ctx, srv.endpoint());
  peer.send(test::make_hello(3, cam));
  ASSERT_TRUE(next_of(peer, wire::ServerMessage::kWelcome));
  peer.send(test::make_frame(3, std::numeric_limits<std::uint64_t>::max(), 0.0, cam));
  EXPECT_EQ(next_error(peer), wire::ERROR_SEQ_JUMP);
  peer.send(test::make_frame(3, 1001, 0.0, cam));
  EXPECT_EQ(next_error(peer), wire::ERROR_SEQ_JUMP);
  peer.send(test::make_frame(3, 1000, 0.0, cam));  // exactly the bound: accepted
  auto ack = next_of(peer, wire::ServerMessage::kAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->ack().seq(), 1000u);
  peer.send(test::make_frame(3, 1001, 0.1, cam));  // and the session goes on
  ack = next_of(peer, wire::ServerMessage::kAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->ack().seq(), 1001u);
  srv.stop();
  EXPECT_EQ(srv.stats().clients().at(3).dropped.at("seq_jump"), 2u);
}

// Smaller finding: a bad hello naming a victim's id was counted in the victim's drop counter.
TEST(Hardening, BadHelloWithAVictimsIdIsNotCountedAgainstTheVictim) {
  server::ReceiverConfig rc;
  test::InProcessServer srv(rc, counting_system());
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  test::RawPeer victim(ctx, srv.endpoint()), attacker(ctx, srv.endpoint());
  victim.send(test::make_hello(4, cam));
  ASSERT_TRUE(next_of(victim, wire::ServerMessage::kWelcome));
  PinholeCamera other = cam;
  other.fx = 99;  // a different camera: refused
  attacker.send(test::make_hello(4, other));
  EXPECT_NE(next_error(attacker), wire::ERROR_UNSPECIFIED);
  wire::ClientMessage bad = test::make_hello(4, cam);
  bad.mutable_hello()->set_version(wire::ProtocolVersion(99));
  attacker.send(bad);
  EXPECT_EQ(next_error(attacker), wire::ERROR_BAD_VERSION);
  srv.stop();
  EXPECT_EQ(srv.stats().clients().at(4).dropped_total(), 0u);
  std::uint64_t unattributed = 0;
  for (const auto& [reason, n] : srv.stats().unattributed()) unattributed += n;
  EXPECT_EQ(unattributed, 2u);
}

// Case 3: a hello may not announce a camera whose frames decode to hundreds of megabytes.
TEST(Hardening, HugeCameraIsRefusedAtHello) {
  server::ReceiverConfig rc;
  test::InProcessServer srv(rc, counting_system());
  zmq::context_t ctx(1);
  test::RawPeer peer(ctx, srv.endpoint());
  PinholeCamera huge = small_camera();
  huge.width = huge.height = 8192;
  huge.cx = huge.cy = 4096;
  peer.send(test::make_hello(1, huge));
  EXPECT_EQ(next_error(peer), wire::ERROR_BAD_HELLO);
  PinholeCamera hd = small_camera();
  hd.width = 1920;
  hd.height = 1080;
  hd.cx = 960;
  hd.cy = 540;
  hd.fx = hd.fy = 1000;                // within [0.1, 10] x the image size
  peer.send(test::make_hello(2, hd));  // the default limit is 1920 x 1080
  EXPECT_TRUE(next_of(peer, wire::ServerMessage::kWelcome));
  srv.stop();
  EXPECT_FALSE(srv.system().has_client(1));
}

// Case 4: 1000 hellos with new ids leave at most --max-clients sessions and a bounded thread count.
TEST(Hardening, ThousandHellosLeaveAtMostMaxClientsSessions) {
  const std::size_t before = thread_count();
  server::ReceiverConfig rc;
  rc.max_clients = 16;
  test::InProcessServer srv(rc, counting_system());
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  test::RawPeer flood(ctx, srv.endpoint());  // starts this context's own I/O threads
  const std::size_t idle_server = thread_count();
  for (ClientId id = 1; id <= 1000; ++id) flood.send(test::make_hello(id, cam));
  std::size_t welcomes = 0, refused = 0;
  while (welcomes + refused < 1000) {
    const auto r = flood.receive(10000);
    ASSERT_TRUE(r) << welcomes << " welcomes, " << refused << " refusals";
    if (r->has_welcome()) ++welcomes;
    if (r->has_error() && r->error().code() == wire::ERROR_TOO_MANY_CLIENTS) ++refused;
  }
  EXPECT_EQ(welcomes, 16u);
  EXPECT_EQ(refused, 984u);
  const auto status = wait_status(srv, [](const http::NetStatus& s) { return s.totals.count("sessions"); });
  ASSERT_TRUE(status);
  EXPECT_EQ(status->totals.at("sessions"), 16u);
  EXPECT_LE(status->clients.size(), 16u);
  EXPECT_GT(status->totals.at("process_threads"), 16u);  // the live thread count
  // One worker thread per client without SLAM (docs/security.md counts them with SLAM).
  EXPECT_LE(test::thread_count_settled_to(idle_server + 16), idle_server + 16);
  EXPECT_GT(thread_count(), before);
}

// Case 4, second half, and the smaller "idle, not disconnected" finding: a vanished client shows
// as disconnected, its session is reclaimed after the TTL (outputs written), and the id may then
// start a new session.
TEST(Hardening, VanishedClientIsDisconnectedThenReclaimed) {
  const std::string out = test::scratch_dir("reclaim");
  server::ReceiverConfig rc;
  rc.heartbeat_timeout_s = 0.3;
  rc.session_ttl_s = 0.6;
  rc.reclaim_dir = out;
  test::InProcessServer srv(rc, counting_system());
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  {
    test::RawPeer peer(ctx, srv.endpoint());
    peer.send(test::make_hello(6, cam));
    ASSERT_TRUE(next_of(peer, wire::ServerMessage::kWelcome));
    for (std::uint64_t seq = 1; seq <= 3; ++seq) {
      peer.send(test::make_frame(6, seq, double(seq), cam));
      ASSERT_TRUE(next_of(peer, wire::ServerMessage::kAck));
    }
    auto s = wait_status(srv, [](const http::NetStatus& s) { return s.clients.count(6) > 0; });
    ASSERT_TRUE(s && s->clients.count(6));
    EXPECT_EQ(s->clients.at(6).connection, "active");
    // A network status published before the hello (it is refreshed every 0.2 s) does not make
    // a client that is streaming look reclaimed.
    http::StatusCache early(srv.system(), http::CacheConfig());
    http::NetStatusBoard before_hello;
    before_hello.publish(std::make_shared<http::NetStatus>());
    early.set_network(&before_hello);
    early.refresh();
    ASSERT_EQ(early.get()->status["clients"].size(), 1u);
    EXPECT_NE(early.get()->status["clients"][0]["connection"], "reclaimed");
  }  // vanishes without goodbye
  auto s = wait_status(
      srv, [](const http::NetStatus& s) { return s.clients.count(6) && s.clients.at(6).connection == "disconnected"; });
  ASSERT_TRUE(s && s->clients.count(6));
  EXPECT_EQ(s->clients.at(6).connection, "disconnected");
  // The HTTP status shows it too.
  http::StatusCache cache(srv.system(), http::CacheConfig());
  http::NetStatusBoard board;
  board.publish(s);
  cache.set_network(&board);
  cache.refresh();
  const auto state = cache.get();
  ASSERT_EQ(state->status["clients"].size(), 1u);
  EXPECT_EQ(state->status["clients"][0]["connection"], "disconnected");

  s = wait_status(
      srv, [](const http::NetStatus& s) { return s.clients.count(6) == 0 && s.totals.at("sessions_reclaiming") == 0; });
  ASSERT_TRUE(s);
  EXPECT_EQ(s->clients.count(6), 0u);
  EXPECT_EQ(s->totals.at("sessions_reclaimed"), 1u);
  EXPECT_FALSE(srv.system().has_client(6));
  EXPECT_EQ(test::trajectory_lines(out + "/client_6-1/client_6.txt").size(), 3u);
  // The id may come back: a new session.
  test::RawPeer again(ctx, srv.endpoint());
  again.send(test::make_hello(6, cam));
  const auto w = next_of(again, wire::ServerMessage::kWelcome);
  ASSERT_TRUE(w);
  EXPECT_FALSE(w->welcome().resumed());
  EXPECT_EQ(w->welcome().last_seq(), 0u);
  std::filesystem::remove_all(out);
}

// Without CURVE, a restarted client resumes only once its old connection timed out; the client
// library retries by itself.
TEST(Hardening, ClientResumesAfterItsOldConnectionTimedOut) {
  server::ReceiverConfig rc;
  rc.heartbeat_timeout_s = 0.5;
  test::InProcessServer srv(rc, counting_system());
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  test::RawPeer first(ctx, srv.endpoint());
  first.send(test::make_hello(8, cam));
  ASSERT_TRUE(next_of(first, wire::ServerMessage::kWelcome));
  first.send(test::make_frame(8, 1, 0.0, cam));
  ASSERT_TRUE(next_of(first, wire::ServerMessage::kAck));
  first.close();  // killed: the session is still active for heartbeat_timeout_s
  client::SenderConfig cc;
  cc.server = srv.endpoint();
  cc.info.id = 8;
  cc.info.camera = cam;
  cc.reply_timeout_s = 20;
  client::FrameSender second(cc);
  second.connect();  // refused as busy at first, then resumed
  EXPECT_EQ(second.last_seq(), 1u);
  EXPECT_GE(second.stats().errors.at("ERROR_SESSION_BUSY"), 1u);
  EXPECT_EQ(second.stats().frames_refused, 0u);
}

// Smaller finding: after a server restart a client that delivered everything exited with 1
// (a heartbeat's "not registered" was counted as a failure). Only refused frames count now.
TEST(Hardening, ServerRestartDoesNotFailAClientThatDeliveredEverything) {
  server::ReceiverConfig rc;
  auto first = std::make_unique<test::InProcessServer>(rc, counting_system());
  const std::string endpoint = first->endpoint();
  client::SenderConfig cc;
  cc.server = endpoint;
  cc.info.id = 2;
  cc.info.camera = small_camera();
  cc.reply_timeout_s = 20;
  cc.heartbeat_interval_s = 0.1;
  client::FrameSender sender(cc);
  sender.connect();
  RgbdFrame frame;
  frame.bgr = cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3));
  frame.depth = cv::Mat(48, 64, CV_16UC1, cv::Scalar(3000));
  for (int i = 0; i < 3; ++i) {
    frame.timestamp = i;
    sender.send_frame(frame);
  }
  sender.keep_alive(0.5);
  ASSERT_EQ(sender.in_flight(), 0u);
  first.reset();  // server gone
  server::ReceiverConfig again = rc;
  again.bind = endpoint;  // restarted on the same port
  test::InProcessServer second(again, counting_system());
  sender.keep_alive(1.5);  // heartbeat -> not registered -> the sender says hello again
  for (int i = 3; i < 5; ++i) {
    frame.timestamp = i;
    sender.send_frame(frame);
  }
  EXPECT_TRUE(sender.goodbye(20));
  EXPECT_GE(sender.stats().reconnects, 1u);
  EXPECT_EQ(sender.stats().errors.count("ERROR_NOT_REGISTERED"), 1u);  // what used to fail the run
  EXPECT_EQ(sender.stats().frames_refused, 0u);                        // cslam-client exits 0 on this
}

// Case 7: the network counters are live (not only in network_stats.json at exit).
TEST(Hardening, NetworkCountersAreLiveInMetricsAndStatus) {
  server::ReceiverConfig rc;
  test::InProcessServer srv(rc, counting_system());
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  test::RawPeer peer(ctx, srv.endpoint());
  peer.send_bytes("garbage");
  EXPECT_EQ(next_error(peer), wire::ERROR_MALFORMED);
  peer.send(test::make_hello(11, cam));
  ASSERT_TRUE(next_of(peer, wire::ServerMessage::kWelcome));
  peer.send(test::make_frame(11, 1, 0.0, cam));
  ASSERT_TRUE(next_of(peer, wire::ServerMessage::kAck));
  peer.send(test::make_frame(11, 1, 0.0, cam));
  EXPECT_EQ(next_error(peer), wire::ERROR_DUPLICATE_SEQ);
  const auto s = wait_status(srv, [](const http::NetStatus& s) {
    return s.clients.count(11) && s.clients.at(11).dropped.count("duplicate_seq");
  });
  ASSERT_TRUE(s && s->clients.count(11));
  EXPECT_EQ(s->unattributed.at("malformed"), 1u);
  EXPECT_EQ(s->clients.at(11).counters.at("frames_accepted"), 1u);
  const std::string metrics = http::network_metrics_text(*s);
  EXPECT_NE(metrics.find("cslam_net_unattributed_dropped_total{reason=\"malformed\"} 1"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("cslam_net_client_frames_accepted_total{client=\"11\"} 1"), std::string::npos);
  EXPECT_NE(metrics.find("cslam_net_client_dropped_by_reason_total{client=\"11\",reason=\"duplicate_seq\"} 1"),
            std::string::npos);
  EXPECT_NE(metrics.find("cslam_net_bytes_received_total "), std::string::npos);
  const nlohmann::json j = http::network_json(*s);
  EXPECT_EQ(j["unattributed"]["malformed"], 1);
  EXPECT_EQ(j["clients"][0]["frames_accepted"], 1);
}

}  // namespace
}  // namespace cslam
