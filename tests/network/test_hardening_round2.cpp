// Hardening, round 2 (docs/security.md): implausible cameras at hello, one wild timestamp, and
// trajectory writers. Each test reproduces a case the server got wrong at feb1370.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "client/frame_sender.h"
#include "common/run_program.h"
#include "eval/trajectory_eval.h"
#include "geometry/camera_io.h"
#include "io/trajectory_io.h"
#include "io/tum_dataset.h"
#include "net_test_util.h"

namespace cslam {
namespace {

PinholeCamera qvga() {
  PinholeCamera c;
  c.name = "qvga";
  c.width = 320;
  c.height = 240;
  c.fx = c.fy = 260;
  c.cx = 159.5;
  c.cy = 119.5;
  return c;
}

SystemConfig counting_system() {
  SystemConfig sc;
  sc.run_slam = false;
  return sc;
}

std::optional<wire::ServerMessage> next_of(test::RawPeer& peer, wire::ServerMessage::BodyCase kind, int tries = 20) {
  for (int i = 0; i < tries; ++i) {
    auto reply = peer.receive(5000);
    if (!reply) return std::nullopt;
    if (reply->body_case() == kind) return reply;
  }
  return std::nullopt;
}

// The reply to frame `seq`: its ack or its error (acks of other frames skipped).
std::optional<wire::ServerMessage> reply_to(test::RawPeer& peer, std::uint64_t seq) {
  for (int i = 0; i < 20; ++i) {
    auto r = peer.receive(5000);
    if (!r) return std::nullopt;
    if (r->has_ack() && r->ack().seq() == seq) return r;
    if (r->has_error() && r->error().seq() == seq) return r;
  }
  return std::nullopt;
}

// The hello's ERROR_BAD_HELLO message, or "" if it was welcomed.
std::string hello_refusal(const PinholeCamera& cam) {
  try {
    wire::from_hello(test::make_hello(1, cam).hello(), "test", 1920 * 1080);
    return "";
  } catch (const wire::WireError& e) {
    EXPECT_EQ(e.code(), wire::ERROR_BAD_HELLO) << e.what();
    return e.what();
  }
}

// Item 1: a principal point outside the image.
TEST(HardeningRound2, PrincipalPointOutsideTheImageIsABadHello) {
  EXPECT_EQ(hello_refusal(qvga()), "");
  for (auto [cx, cy] : {std::pair{-1000.0, 119.5}, {3200.0, 119.5}, {159.5, -5.0}, {159.5, 1e9}}) {
    PinholeCamera c = qvga();
    c.cx = cx;
    c.cy = cy;
    const std::string why = hello_refusal(c);
    EXPECT_NE(why.find("principal point"), std::string::npos) << cx << " " << cy << ": " << why;
    EXPECT_NE(why.find("outside the 320x240 image"), std::string::npos) << why;
  }
  PinholeCamera edge = qvga();  // on the border: still inside
  edge.cx = 320;
  edge.cy = 0;
  EXPECT_EQ(hello_refusal(edge), "");
}

// Item 2: one-pixel cameras and focal lengths far from the image size.
TEST(HardeningRound2, TinyCamerasAndAbsurdFocalLengthsAreBadHellos) {
  for (auto [w, h] : {std::pair{1, 1}, {1, 240}, {320, 1}, {47, 240}, {320, 47}}) {
    PinholeCamera c = qvga();
    c.width = w;
    c.height = h;
    c.cx = w / 2.0;
    c.cy = h / 2.0;
    c.fx = c.fy = std::max(w, h);
    const std::string why = hello_refusal(c);
    EXPECT_NE(why.find("below the minimum 48x48"), std::string::npos) << w << "x" << h << ": " << why;
  }
  PinholeCamera smallest = qvga();
  smallest.width = smallest.height = 48;
  smallest.cx = smallest.cy = 24;
  smallest.fx = smallest.fy = 40;
  EXPECT_EQ(hello_refusal(smallest), "");
  for (auto [fx, fy] : {std::pair{31.0, 260.0}, {260.0, 23.0}, {3201.0, 260.0}, {260.0, 2401.0}, {1e-3, 1e-3}}) {
    PinholeCamera c = qvga();
    c.fx = fx;
    c.fy = fy;
    const std::string why = hello_refusal(c);
    EXPECT_NE(why.find("focal lengths"), std::string::npos) << fx << " " << fy << ": " << why;
    EXPECT_NE(why.find("[0.1, 10]"), std::string::npos) << why;
  }
  for (auto [fx, fy] : {std::pair{32.0, 24.0}, {3200.0, 2400.0}}) {  // the bounds themselves
    PinholeCamera c = qvga();
    c.fx = fx;
    c.fy = fy;
    EXPECT_EQ(hello_refusal(c), "") << fx;
  }
}

// Items 1 and 2 over the wire: each implausible camera gets ERROR_BAD_HELLO with its reason, takes
// no session slot, and a good robot on the same server is welcomed and acked.
TEST(HardeningRound2, ServerRefusesImplausibleCamerasAndServesTheGoodRobot) {
  server::ReceiverConfig rc;
  test::InProcessServer srv(rc, counting_system());
  zmq::context_t ctx(1);
  test::RawPeer hostile(ctx, srv.endpoint()), robot(ctx, srv.endpoint());
  std::vector<PinholeCamera> bad;
  for (double cx : {-1000.0, 3200.0}) bad.push_back(qvga()), bad.back().cx = cx;
  for (double cy : {-5.0, 1e9}) bad.push_back(qvga()), bad.back().cy = cy;
  for (auto [w, h] : {std::pair{1, 1}, {1, 240}, {320, 1}}) {
    bad.push_back(qvga());
    bad.back().width = w;
    bad.back().height = h;
    bad.back().cx = bad.back().cy = 0.5;
  }
  ClientId id = 10;
  for (const PinholeCamera& c : bad) {
    hostile.send(test::make_hello(id++, c));
    const auto e = next_of(hostile, wire::ServerMessage::kError);
    ASSERT_TRUE(e);
    EXPECT_EQ(e->error().code(), wire::ERROR_BAD_HELLO) << e->error().message();
    EXPECT_NE(e->error().message().find("camera"), std::string::npos) << e->error().message();
  }
  EXPECT_EQ(srv.sessions().size(), 0u);
  robot.send(test::make_hello(1, qvga()));
  ASSERT_TRUE(next_of(robot, wire::ServerMessage::kWelcome));
  for (std::uint64_t seq = 1; seq <= 3; ++seq) {
    robot.send(test::make_frame(1, seq, 1.0 + 0.033 * double(seq), qvga()));
    const auto r = reply_to(robot, seq);
    ASSERT_TRUE(r);
    EXPECT_TRUE(r->has_ack()) << r->DebugString();
  }
  srv.stop();
  EXPECT_EQ(srv.sessions().size(), 1u);
}

// Item 3: one frame stamped 1e6 s ahead is refused with ERROR_TIMESTAMP_JUMP, and the robot's
// next, correctly stamped frames are tracked (SLAM on: they used to be "does not increase").
TEST(HardeningRound2, OneWildTimestampIsRefusedAndTheSessionGoesOn) {
  server::ReceiverConfig rc;
  test::InProcessServer srv(rc, SystemConfig());
  zmq::context_t ctx(1);
  test::RawPeer robot(ctx, srv.endpoint());
  const PinholeCamera cam = qvga();
  robot.send(test::make_hello(1, cam));
  ASSERT_TRUE(next_of(robot, wire::ServerMessage::kWelcome));
  std::uint64_t seq = 0;
  double t = 100.0;
  auto send = [&](double stamp) {
    robot.send(test::make_frame(1, ++seq, stamp, cam));
    return reply_to(robot, seq);
  };
  for (int i = 0; i < 5; ++i) {
    const auto r = send(t += 0.033);
    ASSERT_TRUE(r && r->has_ack()) << (r ? r->DebugString() : "no reply");
    EXPECT_NE(r->ack().state(), wire::TRACK_REJECTED);
  }
  const auto wild = send(t + 1e6);
  ASSERT_TRUE(wild);
  EXPECT_TRUE(wild->has_error()) << wild->DebugString();
  EXPECT_EQ(wild->error().code(), wire::ERROR_TIMESTAMP_JUMP);
  EXPECT_NE(wild->error().message().find("past the last accepted frame"), std::string::npos) << wild->error().message();
  for (int i = 0; i < 5; ++i) {
    const auto r = send(t += 0.033);
    ASSERT_TRUE(r);
    ASSERT_TRUE(r->has_ack()) << r->DebugString();
    EXPECT_NE(r->ack().state(), wire::TRACK_REJECTED) << "frame at " << t << " after the wild one";
  }
  srv.stop();
  EXPECT_EQ(srv.stats().clients().at(1).dropped_total(), 1u);
}

// The bound itself (no clock: time points given).
TEST(HardeningRound2, TimestampBoundFollowsTheSessionsFrameIntervalAndWallClock) {
  using server::Clock;
  server::TimestampBound bound;  // 10 s floor, 100 x median interval, 2 x wall seconds, 3 to confirm
  server::StampHistory h;
  const Clock::time_point t0{};
  double t = 5.0;
  auto at = [&t0](double s) {
    return t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
  };
  EXPECT_TRUE(h.check(1e9, t0, bound).ok);  // the first frame sets the clock
  h.accept(t, t0);
  for (int i = 1; i <= 40; ++i) {
    ASSERT_TRUE(h.check(t + 0.5, at(0.01 * i), bound).ok);
    h.accept(t += 0.5, at(0.01 * i));  // 2 Hz, sent fast (a replay)
  }
  EXPECT_DOUBLE_EQ(h.median_interval(), 0.5);
  const auto now = at(0.4);
  EXPECT_NEAR(h.allowed_jump(now, bound), 50.0, 1e-9);  // 100 x 0.5 s; the wall term is 0 here
  EXPECT_TRUE(h.check(t + 49, now, bound).ok);
  const auto refused = h.check(t + 1e6, now, bound);
  EXPECT_FALSE(refused.ok);
  EXPECT_NE(refused.message.find("at most 50 s"), std::string::npos) << refused.message;
  EXPECT_TRUE(h.check(t + 0.5, now, bound).ok);  // the next good frame: accepted
  EXPECT_DOUBLE_EQ(h.last(), t);                 // and the refused one changed nothing
  // A robot paused for an hour may come back an hour later.
  EXPECT_TRUE(h.check(t + 3600, at(0.4 + 3600), bound).ok);
  // A genuine jump of the time base: taken at the third agreeing frame.
  EXPECT_FALSE(h.check(t + 500, now, bound).ok);
  EXPECT_FALSE(h.check(t + 500.5, now, bound).ok);
  const auto third = h.check(t + 501, now, bound);
  EXPECT_TRUE(third.ok);
  EXPECT_TRUE(third.new_epoch);
  h.accept(t + 501, now);
  EXPECT_EQ(h.median_interval(), 0.0);  // the history restarts there
  EXPECT_TRUE(h.check(t + 501.5, now, bound).ok);
  bound.min_jump_s = 0;  // off
  EXPECT_TRUE(h.check(1e300, now, bound).ok);
}

// Item 3, the writers: a 1e300 or non-finite stamp is never printed (it was a 300-digit number).
TEST(HardeningRound2, TrajectoryWritersLeaveAbsurdStampsOut) {
  const test::ScratchDir dir("round2-traj");
  const std::string path = dir.path() + "/t.txt";
  Trajectory t{{1.0, SE3()}, {1e300, SE3()}, {std::nan(""), SE3()}, {-1e12, SE3()}, {2.0, SE3()}};
  write_tum_trajectory(path, t, "test");
  std::ifstream in(path);
  std::string line, text;
  std::size_t data = 0, longest = 0;
  while (std::getline(in, line)) {
    text += line + "\n";
    longest = std::max(longest, line.size());
    data += !line.empty() && line[0] != '#';
  }
  EXPECT_EQ(data, 2u) << text;
  EXPECT_LT(longest, 120u) << text;
  EXPECT_NE(text.find("# 3 poses with a non-finite or out-of-range timestamp left out"), std::string::npos) << text;
  EXPECT_EQ(read_tum_trajectory(path).size(), 2u);
  EXPECT_LT(format_tum_line({1e300, SE3()}).size(), 120u);
  EXPECT_TRUE(tum_stamp_ok(1.7e9));
  EXPECT_FALSE(tum_stamp_ok(1e300));
}

// The robot beside a hostile peer: a synthetic 60-frame sequence streamed with SLAM on (mapping
// in the worker: deterministic), alone and again while another peer sends every round-2 case
// (implausible cameras; on its own session, wild timestamps). The robot gets every frame acked,
// none refused, the same number of poses, and the same accuracy against the ground truth.
struct RobotRun {
  std::size_t frames = 0, acks = 0, refused = 0, poses = 0;
  double ate_rmse = 0;
  std::size_t hostile_errors = 0;
};

RobotRun stream_robot(const std::string& data, bool hostile) {
  const TumDataset dataset = open_tum_dataset(data);
  server::ReceiverConfig rc;
  SystemConfig sc;
  sc.slam.threaded = false;
  test::InProcessServer srv(rc, sc);
  zmq::context_t ctx(1);
  test::RawPeer peer(ctx, srv.endpoint());
  client::SenderConfig cc;
  cc.server = srv.endpoint();
  cc.info.id = 1;
  cc.info.name = "robot";
  cc.info.camera = load_camera_file(data + "/camera.yaml");
  cc.reply_timeout_s = 60;
  client::FrameSender sender(cc);
  sender.connect();
  RobotRun run;
  PinholeCamera bad = qvga();
  std::uint64_t hostile_seq = 0;
  if (hostile) {
    peer.send(test::make_hello(9, qvga()));  // a session of its own for the wild stamps
    next_of(peer, wire::ServerMessage::kWelcome);
    peer.send(test::make_frame(9, ++hostile_seq, 1.0, qvga()));  // its clock starts sane (the first frame sets it)
  }
  for (const RgbdPair& pair : dataset.pairs) {
    RgbdFrame f;
    f.timestamp = pair.rgb_time;
    f.bgr = cv::imread(pair.rgb_path, cv::IMREAD_COLOR);
    f.depth = cv::imread(pair.depth_path, cv::IMREAD_UNCHANGED);
    sender.send_frame(f);
    ++run.frames;
    if (!hostile) continue;
    const int k = int(run.frames % 4);
    bad = qvga();
    if (k == 0) bad.cx = -1000;
    if (k == 1) bad.width = bad.height = 1;
    if (k == 2) bad.fx = 1e-3;
    if (k == 3) bad.cy = 1e9;
    peer.send(test::make_hello(ClientId(20 + k), bad));
    peer.send(test::make_frame(9, ++hostile_seq,
                               run.frames % 2 ? 1e6 * double(run.frames) : 1.0 + 0.03 * double(run.frames), qvga()));
  }
  EXPECT_TRUE(sender.goodbye(60));
  run.acks = sender.stats().acks;
  run.refused = sender.stats().frames_refused;
  if (hostile)
    for (auto r = peer.receive(200); r; r = peer.receive(200)) run.hostile_errors += r->has_error();
  srv.stop();
  const Trajectory est = srv.system().trajectories().at(1);
  run.poses = est.size();
  run.ate_rmse = compute_ate(*dataset.groundtruth, est, Alignment::kSE3).stats.rmse;
  return run;
}

TEST(HardeningRound2, RobotBesideAHostilePeerGetsAllItsPosesAtUnchangedAccuracy) {
  test::TempDir dir("cslam_round2_beside");
  const std::string data = test::render_small_scene(dir / "scene");
  const RobotRun alone = stream_robot(data, false);
  const RobotRun beside = stream_robot(data, true);
  std::cout << "robot alone: " << alone.poses << " poses of " << alone.frames << ", ATE " << alone.ate_rmse
            << " m; beside the hostile peer: " << beside.poses << " poses, ATE " << beside.ate_rmse << " m, "
            << beside.hostile_errors << " errors answered to the peer\n";
  EXPECT_EQ(beside.acks, beside.frames);
  EXPECT_EQ(beside.refused, 0u);
  EXPECT_EQ(beside.poses, alone.poses);
  EXPECT_GT(alone.poses, alone.frames / 2);
  EXPECT_NEAR(beside.ate_rmse, alone.ate_rmse, 1e-3 + 0.05 * alone.ate_rmse) << "alone " << alone.ate_rmse;
  EXPECT_GE(beside.hostile_errors, beside.frames);  // every bad hello and wild stamp was answered with an error
}

}  // namespace
}  // namespace cslam
