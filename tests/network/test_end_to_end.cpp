// End to end over loopback TCP with the real programs: cslam-server and cslam-client processes.
#include <algorithm>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "geometry/camera_io.h"
#include "net_test_util.h"

namespace cslam {
namespace {

const std::string kBin = CSLAM_BIN_DIR;

struct RunDirs {
  std::string dir, out, endpoint_file;
};

RunDirs make_run(const std::string& name) {
  RunDirs r;
  r.dir = test::scratch_dir(name);
  r.out = r.dir + "/out";
  r.endpoint_file = r.dir + "/endpoint";
  return r;
}

std::vector<std::string> server_args(const RunDirs& r, int clients, std::vector<std::string> extra = {}) {
  std::vector<std::string> a = {kBin + "/cslam-server",
                                "--bind",
                                "tcp://127.0.0.1:*",
                                "--endpoint-file",
                                r.endpoint_file,
                                "--out-dir",
                                r.out,
                                "--no-slam",
                                "--log-interval",
                                "1",
                                "--http",
                                "off"};  // no HTTP viewer: parallel runs must not share its port
  if (clients > 0) {
    a.insert(a.end(), {"--clients", std::to_string(clients), "--exit-when-done"});
  }
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

std::vector<std::string> client_args(const std::string& endpoint, int id, const std::string& dataset,
                                     const std::string& range, const std::string& rate) {
  return {kBin + "/cslam-client",
          "--server",
          endpoint,
          "--id",
          std::to_string(id),
          "--dataset",
          dataset,
          "--range",
          range,
          "--rate",
          rate};
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

class EndToEnd : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(std::filesystem::exists(kBin + "/cslam-server")) << "build cslam-server first";
    ASSERT_TRUE(std::filesystem::exists(kBin + "/cslam-client")) << "build cslam-client first";
    data_ = test::scratch_dir("data");
    test::write_tiny_dataset(data_, 20);
  }
  void TearDown() override {
    if (!HasFailure()) std::filesystem::remove_all(data_);
  }
  std::string data_;
};

TEST_F(EndToEnd, TwoClientProcessesServerExitsByItself) {
  const RunDirs r = make_run("e2e");
  test::ChildProcess server(server_args(r, 2), r.dir + "/server.log");
  const auto endpoint = test::wait_for_file_line(r.endpoint_file, 10);
  ASSERT_TRUE(endpoint) << "server did not start, see " << r.dir << "/server.log";
  test::ChildProcess c1(client_args(*endpoint, 1, data_, "1:20", "max"), r.dir + "/client1.log");
  test::ChildProcess c2(client_args(*endpoint, 2, data_, "5:16", "60"), r.dir + "/client2.log");
  EXPECT_EQ(c1.wait(60), 0) << "see " << r.dir << "/client1.log";
  EXPECT_EQ(c2.wait(60), 0) << "see " << r.dir << "/client2.log";
  EXPECT_EQ(server.wait(30), 0) << "see " << r.dir << "/server.log";
  EXPECT_EQ(test::trajectory_lines(r.out + "/client_1.txt").size(), 20u);
  EXPECT_EQ(test::trajectory_lines(r.out + "/client_2.txt").size(), 12u);
  const auto stats = read_json(r.out + "/network_stats.json");
  ASSERT_EQ(stats["clients"].size(), 2u);
  for (const auto& c : stats["clients"]) {
    EXPECT_EQ(c["dropped_total"], 0);
    EXPECT_EQ(c["goodbyes"], 1);
    EXPECT_EQ(c["frames_accepted"], c["frames_processed"]);
  }
  if (!HasFailure()) std::filesystem::remove_all(r.dir);
}

// Full SLAM over the network: two robots of the small synthetic scene stream to the server, whose
// fusion thread fuses their maps; stats.json shows the fusion event and one group.
TEST_F(EndToEnd, TwoRobotsFuseOverTheNetwork) {
  const RunDirs r = make_run("e2e_fusion");
  test::ChildProcess synth({kBin + "/cslam-synth", "--preset", "test-small", "--seed", "5", "--out", r.dir + "/scene",
                            "--log-level", "warn"},
                           r.dir + "/synth.log");
  ASSERT_EQ(synth.wait(120), 0) << "see " << r.dir << "/synth.log";
  auto args = server_args(r, 2);
  args.erase(std::find(args.begin(), args.end(), "--no-slam"));
  test::ChildProcess server(args, r.dir + "/server.log");
  const auto endpoint = test::wait_for_file_line(r.endpoint_file, 10);
  ASSERT_TRUE(endpoint) << "server did not start, see " << r.dir << "/server.log";
  test::ChildProcess c1(client_args(*endpoint, 1, r.dir + "/scene/robot_1", "1:", "30"), r.dir + "/client1.log");
  test::ChildProcess c2(client_args(*endpoint, 2, r.dir + "/scene/robot_2", "1:", "30"), r.dir + "/client2.log");
  EXPECT_EQ(c1.wait(120), 0) << "see " << r.dir << "/client1.log";
  EXPECT_EQ(c2.wait(120), 0) << "see " << r.dir << "/client2.log";
  EXPECT_EQ(server.wait(120), 0) << "see " << r.dir << "/server.log";
  const auto stats = read_json(r.out + "/stats.json");
  ASSERT_GE(stats["fusion_events"].size(), 1u) << stats.dump(2);
  const auto& e = stats["fusion_events"][0];
  EXPECT_GT(e["inliers"].get<int>(), 0);
  EXPECT_GT(e["seam_points"].get<int>(), 0);
  ASSERT_EQ(stats["clients"].size(), 2u);
  EXPECT_EQ(stats["clients"][0]["group"], stats["clients"][1]["group"]);
  EXPECT_TRUE(stats["clients"][0]["fused"].get<bool>());
  bool fused_file = false;
  for (const auto& entry : std::filesystem::directory_iterator(r.out))
    fused_file = fused_file || entry.path().filename().string().rfind("fused_", 0) == 0;
  EXPECT_TRUE(fused_file) << "no fused_G.txt in " << r.out;
  EXPECT_EQ(test::trajectory_lines(r.out + "/client_1.txt").size(), 60u);
  EXPECT_EQ(test::trajectory_lines(r.out + "/client_2.txt").size(), 60u);
  if (!HasFailure()) std::filesystem::remove_all(r.dir);
}

TEST_F(EndToEnd, ServerStopsOnSigtermAndWritesOutputs) {
  const RunDirs r = make_run("sigterm");
  test::ChildProcess server(server_args(r, 0), r.dir + "/server.log");
  const auto endpoint = test::wait_for_file_line(r.endpoint_file, 10);
  ASSERT_TRUE(endpoint);
  test::ChildProcess c1(client_args(*endpoint, 3, data_, "1:10", "max"), r.dir + "/client.log");
  EXPECT_EQ(c1.wait(60), 0);
  server.terminate();
  EXPECT_EQ(server.wait(30), 0) << "see " << r.dir << "/server.log";
  EXPECT_EQ(test::trajectory_lines(r.out + "/client_3.txt").size(), 10u);
  if (!HasFailure()) std::filesystem::remove_all(r.dir);
}

// One good client and one raw DEALER sending every kind of bad input, then vanishing: the good
// client's trajectory is identical to a run without the bad one, and the bad inputs are counted.
TEST_F(EndToEnd, MisbehavingClientDoesNotAffectTheGoodOne) {
  const RunDirs reference = make_run("reference");
  {
    test::ChildProcess server(server_args(reference, 1), reference.dir + "/server.log");
    const auto endpoint = test::wait_for_file_line(reference.endpoint_file, 10);
    ASSERT_TRUE(endpoint);
    test::ChildProcess good(client_args(*endpoint, 1, data_, "1:20", "max"), reference.dir + "/good.log");
    ASSERT_EQ(good.wait(60), 0);
    ASSERT_EQ(server.wait(30), 0);
  }
  const RunDirs r = make_run("misbehaving");
  test::ChildProcess server(server_args(r, 1, {"--heartbeat-timeout", "1", "--max-msg-bytes", "500000"}),
                            r.dir + "/server.log");
  const auto endpoint = test::wait_for_file_line(r.endpoint_file, 10);
  ASSERT_TRUE(endpoint);
  test::ChildProcess good(client_args(*endpoint, 1, data_, "1:20", "30"), r.dir + "/good.log");
  {
    zmq::context_t ctx(1);
    test::RawPeer bad(ctx, *endpoint);
    PinholeCamera cam = load_camera(data_ + "/camera.yaml");
    bad.send_bytes(std::string("\x00\x01\x02 not protobuf \xff", 17));
    bad.send(test::make_frame(2, 1, 0.0, cam));  // frame before hello
    bad.send(test::make_hello(2, cam));
    const std::string frame = test::make_frame(2, 1, 0.0, cam).SerializeAsString();
    bad.send_bytes(frame.substr(0, frame.size() - 7));  // truncated protobuf
    wire::ClientMessage m = test::make_frame(2, 1, 0.0, cam);
    m.mutable_frame()->mutable_depth()->set_encoding(wire::Encoding(1234));
    bad.send(m);  // unknown encoding
    PinholeCamera wrong = cam;
    wrong.height = 60;
    bad.send(test::make_frame(2, 1, 0.0, wrong));  // size contradicts the hello
    m = test::make_frame(2, 1, 0.0, cam);
    m.mutable_frame()->mutable_rgb()->set_data(std::string("\xff\xd8\xff\xe0", 4) + std::string(300, '\x07'));
    bad.send(m);  // corrupt JPEG
    bad.send(test::make_frame(2, 2, 0.1, cam));
    bad.send(test::make_frame(2, 2, 0.1, cam));  // duplicate seq
    bad.send(test::make_frame(2, 1, 0.0, cam));  // out of order
    int errors = 0;
    for (auto reply = bad.receive(2000); reply; reply = bad.receive(500)) errors += reply->has_error();
    EXPECT_EQ(errors, 8);
    wire::ClientMessage huge = test::make_frame(2, 3, 0.2, cam);
    huge.mutable_frame()->mutable_rgb()->set_data(std::string(600000, 'z'));
    bad.send(huge);  // over --max-msg-bytes: ZeroMQ drops the connection
    EXPECT_FALSE(bad.receive(300).has_value());
    bad.close();  // vanishes mid-stream, no goodbye
  }
  EXPECT_EQ(good.wait(60), 0) << "see " << r.dir << "/good.log";
  EXPECT_EQ(server.wait(30), 0) << "see " << r.dir << "/server.log";
  const auto expected = test::trajectory_lines(reference.out + "/client_1.txt");
  ASSERT_EQ(expected.size(), 20u);
  EXPECT_EQ(test::trajectory_lines(r.out + "/client_1.txt"), expected);
  const auto stats = read_json(r.out + "/network_stats.json");
  EXPECT_EQ(stats["unattributed"]["malformed"], 1);
  EXPECT_EQ(stats["unattributed"]["not_registered"], 1);
  bool saw_bad = false;
  for (const auto& c : stats["clients"]) {
    if (c["id"] == 1) {
      EXPECT_EQ(c["dropped_total"], 0);
    }
    if (c["id"] == 2) {
      saw_bad = true;
      EXPECT_EQ(c["dropped_total"], 6);
      EXPECT_EQ(c["dropped"]["duplicate_seq"], 2);
      EXPECT_EQ(c["timeouts"], 1);
      EXPECT_EQ(c["frames_accepted"], 1);
    }
  }
  EXPECT_TRUE(saw_bad);
  if (!HasFailure()) std::filesystem::remove_all(reference.dir);
  if (!HasFailure()) std::filesystem::remove_all(r.dir);
}

}  // namespace
}  // namespace cslam
