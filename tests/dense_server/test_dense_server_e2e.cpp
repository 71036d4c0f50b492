// The live dense map over real processes on loopback: two robots stream a synthetic scene to a
// cslam-server started without --datasets-dir (every frame full; robot 1's colour JPEG, robot 2's
// standalone H.264 pictures, the lean stream's full frames' encoding); the server keeps their keyframes' images,
// builds TSDF submaps, follows the map fusion, serves them over HTTP (index with ETags, CSM1 meshes, PLY downloads) and
// writes them at exit. A server killed with SIGKILL and restarted on its
// --state-dir returns the dense map for every keyframe its snapshot holds; keyframes of a snapshot
// whose images were never stored are counted missing.
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <set>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cloud/cloud_metrics.h"
#include "cloud/ply_io.h"
#include "common/run_program.h"
#include "eval/trajectory_eval.h"
#include "io/trajectory_io.h"
#include "network/net_test_util.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include <httplib.h>

namespace cslam {
namespace {

const std::string kBin = CSLAM_BIN_DIR;

std::vector<std::string> server_args(const std::string& run, std::vector<std::string> extra) {
  std::vector<std::string> a = {kBin + "/cslam-server",
                                "--bind",
                                "tcp://127.0.0.1:*",
                                "--endpoint-file",
                                run + "/endpoint",
                                "--out-dir",
                                run + "/out",
                                "--http",
                                "0",
                                "--http-port-file",
                                run + "/http_port",
                                "--log-interval",
                                "2",
                                "--clients",
                                "2"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

std::vector<std::string> client_args(const std::string& endpoint, int id, const std::string& dataset,
                                     std::vector<std::string> extra = {}) {
  std::vector<std::string> a = {
      kBin + "/cslam-client", "--server", endpoint, "--id", std::to_string(id), "--dataset", dataset, "--rate", "30"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

nlohmann::json get_json(httplib::Client& http, const std::string& path) {
  const auto res = http.Get(path);
  if (!res || res->status != 200) return nullptr;
  return nlohmann::json::parse(res->body, nullptr, false);
}

// Waits until the dense map is settled (or timeout_s): everything it was given is integrated,
// meshed and at the current poses.
nlohmann::json wait_dense_idle(httplib::Client& http, double timeout_s) {
  nlohmann::json st;
  for (int i = 0; i < int(timeout_s * 5); ++i) {
    st = get_json(http, "/api/dense/status");
    if (st.is_object() && st.value("enabled", false) && st.value("settled", false) && st["submaps"] > 0) return st;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  return st;
}

class DenseServer : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_dir_ = std::make_unique<test::ScratchDir>("dense_scene");
    scene_ = scene_dir_->path() + "/scene";
    const auto r = test::run_program("cslam-synth", "--preset test-small --frames 200 --seed 5 --overlap 0.3 --out " +
                                                        scene_ + " --force --log-level warn");
    ASSERT_EQ(r.status, 0) << r.output;
  }
  static void TearDownTestSuite() { scene_dir_.reset(); }
  static std::string scene_;
  static std::unique_ptr<test::ScratchDir> scene_dir_;
};
std::string DenseServer::scene_;
std::unique_ptr<test::ScratchDir> DenseServer::scene_dir_;

TEST_F(DenseServer, StreamedRobotsGetALiveDenseMapThatFollowsFusion) {
  const test::ScratchDir run_dir("dense_live");
  const std::string& run = run_dir.path();
  test::ChildProcess server(server_args(run, {}), run + "/server.log");
  const auto endpoint = test::wait_for_file_line(run + "/endpoint", 30);
  const auto port = test::wait_for_file_line(run + "/http_port", 30);
  ASSERT_TRUE(endpoint && port) << "see " << run << "/server.log";
  httplib::Client http("127.0.0.1", std::stoi(*port));
  {
    test::ChildProcess c1(client_args(*endpoint, 1, scene_ + "/robot_1"), run + "/client1.log");
    test::ChildProcess c2(client_args(*endpoint, 2, scene_ + "/robot_2", {"--rgb-codec", "h264-intra"}),
                          run + "/client2.log");
    ASSERT_EQ(c1.wait(300), 0) << "see " << run << "/client1.log";
    ASSERT_EQ(c2.wait(300), 0) << "see " << run << "/client2.log";
  }
  const nlohmann::json st = wait_dense_idle(http, 60);
  ASSERT_TRUE(st.is_object() && st.value("settled", false)) << st.dump() << " see " << run << "/server.log";
  EXPECT_EQ(st["stale_meshes"], 0);
  EXPECT_EQ(st["distorted_submaps"], 0);
  EXPECT_GT(st["keyframes_integrated"].get<int>(), 10);
  EXPECT_EQ(st["missing_images"], 0);
  EXPECT_EQ(st["queue_dropped"], 0);
  EXPECT_EQ(st["store"]["errors"], 0);
  // The store holds what was received: bytes per keyframe of a network frame (JPEG or H.264
  // pictures + zstd here), and every stored keyframe decoded (missing_images 0 above).
  EXPECT_GT(st["store"]["keyframes"].get<int>(), 10);
  // Robot 2 sent H.264 pictures (its log names the codecs).
  std::ifstream log2(run + "/client2.log");
  const std::string log2_text((std::istreambuf_iterator<char>(log2)), std::istreambuf_iterator<char>());
  EXPECT_NE(log2_text.find("codecs h264-intra/zstd"), std::string::npos) << "see " << run << "/client2.log";

  // The robots' maps were fused: one group with both clients' submaps.
  const auto events = get_json(http, "/api/fusion/events");
  ASSERT_TRUE(events.is_object() || events.is_array());
  const auto index_res = http.Get("/api/dense/submaps");
  ASSERT_TRUE(index_res && index_res->status == 200);
  const nlohmann::json index = nlohmann::json::parse(index_res->body);
  ASSERT_EQ(index["groups"].size(), 1u) << index.dump().substr(0, 400);
  const auto& group = index["groups"][0];
  EXPECT_EQ(group["clients"].size(), 2u);
  ASSERT_GT(group["submaps"].size(), 1u);
  // Unchanged index: 304 without a body.
  const std::string etag = index_res->get_header_value("ETag");
  ASSERT_FALSE(etag.empty());
  const auto again = http.Get("/api/dense/submaps", {{"If-None-Match", etag}});
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 304);
  EXPECT_TRUE(again->body.empty());

  // Every submap's mesh: a well-formed CSM1 of its version, sizes as the index says.
  for (const auto& sm : group["submaps"]) {
    const auto res = http.Get(sm["mesh_url"].get<std::string>());
    ASSERT_TRUE(res && res->status == 200) << sm.dump();
    const std::string& b = res->body;
    ASSERT_GE(b.size(), 16u);
    ASSERT_EQ(b.substr(0, 4), "CSM1");
    std::uint32_t version, nv, nt;
    std::memcpy(&version, b.data() + 4, 4);
    std::memcpy(&nv, b.data() + 8, 4);
    std::memcpy(&nt, b.data() + 12, 4);
    EXPECT_EQ(version, sm["version"].get<std::uint32_t>());
    EXPECT_EQ(nv, sm["vertices"].get<std::uint32_t>());
    EXPECT_EQ(nt, sm["triangles"].get<std::uint32_t>());
    EXPECT_GT(nt, 0u);
    EXPECT_EQ(b.size(), 16 + 12 * std::size_t(nv) + (3 * std::size_t(nv) + 3) / 4 * 4 + 12 * std::size_t(nt));
    const auto coarse = http.Get(sm["mesh_url"].get<std::string>() + "?lod=2");
    ASSERT_TRUE(coarse && coarse->status == 200);
    EXPECT_LT(coarse->body.size(), b.size());
  }
  EXPECT_EQ(http.Get("/api/dense/submaps/999999/mesh.bin")->status, 404);
  EXPECT_EQ(http.Get("/api/dense/cloud.ply?group=abc")->status, 400);
  EXPECT_EQ(http.Get("/api/dense/submaps/1/mesh.bin?lod=9")->status, 400);

  // The fused cloud over HTTP, moved into the scene frame by the one SE3 of the fused
  // trajectories, lies on the exact scene surface.
  const auto cloud_res = http.Get("/api/dense/cloud.ply");
  ASSERT_TRUE(cloud_res && cloud_res->status == 200);
  std::ofstream(run + "/live_cloud.ply", std::ios::binary) << cloud_res->body;
  const auto status = get_json(http, "/api/status");
  ASSERT_TRUE(status.is_object());
  EXPECT_TRUE(status.contains("dense"));
  const auto metrics = http.Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_NE(metrics->body.find("cslam_dense_submaps"), std::string::npos);

  // A full-rate rebuild from the keyframe store (no --datasets-dir); the finest request refused.
  const auto refused = http.Post("/api/reconstruction?voxel=0.002&stride=1&mesh=1", "", "text/plain");
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 413) << refused->body;
  const auto started = http.Post("/api/reconstruction?voxel=0.02&stride=4&mesh=0", "", "text/plain");
  ASSERT_TRUE(started && started->status == 202) << (started ? started->body : "no reply");
  const std::string job = nlohmann::json::parse(started->body)["job"];
  nlohmann::json jv;
  for (int i = 0; i < 300; ++i) {
    jv = get_json(http, "/api/reconstruction/" + job);
    if (jv.is_object() && jv["state"] != "queued" && jv["state"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  ASSERT_TRUE(jv.is_object());
  EXPECT_EQ(jv["state"], "done") << jv.dump();
  EXPECT_EQ(jv["frames_used"], st["store"]["keyframes"]) << jv.dump();
  const auto job_cloud = http.Get("/api/reconstruction/" + job + "/cloud.ply");
  ASSERT_TRUE(job_cloud && job_cloud->status == 200);
  EXPECT_EQ(job_cloud->body.rfind("ply\n", 0), 0u);

  server.terminate();
  ASSERT_EQ(server.wait(120), 0) << "see " << run << "/server.log";
  std::vector<std::pair<Trajectory, Trajectory>> pairs;
  for (int k = 1; k <= 2; ++k)
    pairs.emplace_back(read_tum_trajectory(scene_ + "/robot_" + std::to_string(k) + "/groundtruth.txt"),
                       read_tum_trajectory(run + "/out/client_" + std::to_string(k) + ".txt"));
  const auto ate = compute_ate_joint(pairs, Alignment::kSE3, 0.02);
  // The same run's poses and voxel size through the offline reconstruction (every frame, from
  // the image files): the live map, built from keyframes alone, must be as accurate.
  const auto recon = test::run_program(
      "cslam-recon", "--dataset " + scene_ + "/robot_1 " + scene_ + "/robot_2 --poses " + run + "/out/client_1.txt " +
                         run + "/out/client_2.txt --voxel 0.02 --out " + run + "/recon_cloud.ply");
  ASSERT_EQ(recon.status, 0) << recon.output;
  const ColoredCloud scene = read_ply(scene_ + "/scene.ply");
  auto accuracy = [&](const std::string& path) {
    ColoredCloud cloud = read_ply(path);
    const Sim3& T = ate.T_gt_est;  // SE3 alignment: scale 1
    for (auto& p : cloud.points) p = (T.R() * p.cast<double>() + T.translation()).cast<float>();
    return compare_clouds(scene.points, cloud.points, CloudCompareConfig()).test_to_ref;
  };
  const DistanceStats live = accuracy(run + "/live_cloud.ply"), offline = accuracy(run + "/recon_cloud.ply");
  std::printf(
      "vs exact surface (joint ATE %.4f m): live dense cloud C2C median %.1f mm, p95 %.1f mm; offline every-frame "
      "reconstruction %.1f / %.1f mm\n",
      ate.stats.rmse, 1e3 * live.median, 1e3 * live.p95, 1e3 * offline.median, 1e3 * offline.p95);
  // The median as accurate; the tail a little less. Where a robot's trajectory is off by more than a
  // voxel the offline volume averages its frames with the other robot's, while the live map keeps
  // each window in its own submap (here robot 1's last window, poses 2-3 cm off). On the settled map
  // (12 runs, 7 of them beside two busy loops): live p95 34.8-37.3 mm against offline 29.1-32.6 mm,
  // (live - 2 mm) / offline 1.08-1.14, mean 1.10, standard deviation 0.018; a loaded fresh-clone run
  // that read the map before waiting for it to settle gave 1.22. Read before the newest window was
  // meshed, as this test did before `settled`, the live p95 was 19 mm.
  EXPECT_LT(live.median, 1.15 * offline.median + 0.001);
  EXPECT_LT(live.p95, 1.3 * offline.p95 + 0.002);
  // Written at exit too, per group.
  int written = 0;
  for (const auto& e : std::filesystem::directory_iterator(run + "/out"))
    written += e.path().filename().string().rfind("dense_mesh_", 0) == 0;
  EXPECT_EQ(written, 1);
}

TEST_F(DenseServer, KilledServerReturnsTheDenseMapOfEveryKeyframeItsSnapshotHolds) {
  const test::ScratchDir run_dir("dense_kill");
  const std::string& run = run_dir.path();
  const std::string state = run + "/state";
  auto server = std::make_unique<test::ChildProcess>(
      server_args(run, {"--state-dir", state, "--snapshot-interval", "1"}), run + "/server1.log");
  const auto endpoint = test::wait_for_file_line(run + "/endpoint", 30);
  ASSERT_TRUE(endpoint) << "see " << run << "/server1.log";
  {
    test::ChildProcess c1(client_args(*endpoint, 1, scene_ + "/robot_1"), run + "/client1.log");
    ASSERT_EQ(c1.wait(300), 0) << "see " << run << "/client1.log";
  }
  // A snapshot right after the robot's last ack, then SIGKILL: the snapshot stores the keyframes
  // the dense worker has not reached first (DenseService::wait_stored; the worker runs below
  // SLAM's priority, and under two busy loops 20 of 21 keyframes were stored 3 s after the robot
  // finished), so every keyframe it holds comes back with its images.
  {
    const auto port1 = test::wait_for_file_line(run + "/http_port", 30);
    ASSERT_TRUE(port1) << "see " << run << "/server1.log";
    httplib::Client http1("127.0.0.1", std::stoi(*port1));
    http1.set_read_timeout(60, 0);
    const auto written = http1.Post("/api/map/snapshot", "", "application/json");
    ASSERT_TRUE(written && written->status == 200) << (written ? written->body : "no answer");
  }
  server.reset();  // SIGKILL
  std::filesystem::remove(run + "/endpoint");
  std::filesystem::remove(run + "/http_port");
  server = std::make_unique<test::ChildProcess>(server_args(run, {"--state-dir", state}), run + "/server2.log");
  const auto port = test::wait_for_file_line(run + "/http_port", 60);
  ASSERT_TRUE(port) << "see " << run << "/server2.log";
  httplib::Client http("127.0.0.1", std::stoi(*port));
  const nlohmann::json st = wait_dense_idle(http, 120);
  ASSERT_TRUE(st.is_object() && st.value("enabled", false)) << "see " << run << "/server2.log";
  const nlohmann::json status = get_json(http, "/api/status");
  ASSERT_TRUE(status.is_object());
  int keyframes = 0;
  for (const auto& c : status["clients"]) keyframes += c["keyframes"].get<int>();
  ASSERT_GT(keyframes, 5);
  EXPECT_EQ(st["keyframes_integrated"].get<int>(), keyframes) << st.dump();
  EXPECT_EQ(st["missing_images"], 0) << st.dump();
  EXPECT_EQ(st["store"]["keyframes"].get<int>(), keyframes) << st.dump();
  EXPECT_GT(st["submaps"].get<int>(), 0);
  server->terminate();
  EXPECT_EQ(server->wait(120), 0) << "see " << run << "/server2.log";
}

TEST_F(DenseServer, SnapshotKeyframesWithoutStoredImagesAreCountedMissing) {
  const test::ScratchDir run_dir("dense_missing");
  const std::string& run = run_dir.path();
  const std::string state = run + "/state";
  {  // A server without a dense map: its snapshot holds keyframes, its store no images.
    test::ChildProcess server(server_args(run, {"--state-dir", state, "--no-dense"}), run + "/server1.log");
    const auto endpoint = test::wait_for_file_line(run + "/endpoint", 30);
    ASSERT_TRUE(endpoint) << "see " << run << "/server1.log";
    test::ChildProcess c1(client_args(*endpoint, 1, scene_ + "/robot_1"), run + "/client1.log");
    ASSERT_EQ(c1.wait(300), 0) << "see " << run << "/client1.log";
    server.terminate();
    ASSERT_EQ(server.wait(120), 0) << "see " << run << "/server1.log";
  }
  std::filesystem::remove(run + "/endpoint");
  std::filesystem::remove(run + "/http_port");
  test::ChildProcess server(server_args(run, {"--state-dir", state}), run + "/server2.log");
  const auto port = test::wait_for_file_line(run + "/http_port", 60);
  ASSERT_TRUE(port) << "see " << run << "/server2.log";
  httplib::Client http("127.0.0.1", std::stoi(*port));
  const nlohmann::json st = get_json(http, "/api/dense/status"), status = get_json(http, "/api/status");
  ASSERT_TRUE(st.is_object() && status.is_object()) << "see " << run << "/server2.log";
  int keyframes = 0;
  for (const auto& c : status["clients"]) keyframes += c["keyframes"].get<int>();
  ASSERT_GT(keyframes, 5);
  EXPECT_EQ(st["missing_images"].get<int>(), keyframes) << st.dump();
  EXPECT_EQ(st["store"]["keyframes"], 0) << st.dump();
  std::ifstream log(run + "/server2.log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("have no stored images"), std::string::npos);
  server.terminate();
  EXPECT_EQ(server.wait(120), 0) << "see " << run << "/server2.log";
}

}  // namespace
}  // namespace cslam
