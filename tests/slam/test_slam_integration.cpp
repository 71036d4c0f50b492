// End-to-end runs of the offline programs on a small synthetic scene with exact ground truth.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/run_program.h"
#include "io/trajectory_io.h"
#include "io/tum_dataset.h"

using cslam::test::run_program;
using cslam::test::TempDir;

namespace {

// One small scene for the whole suite (2 robots x 60 frames, 320x240).
class SlamIntegration : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("cslam_slam_it");
    const auto r =
        run_program("cslam-synth", "--preset test-small --seed 3 --out " + (*dir_ / "scene") + " --log-level warn");
    ASSERT_EQ(r.status, 0) << r.output;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string scene(const std::string& rel) { return *dir_ / ("scene/" + rel); }
  static std::string tmp(const std::string& rel) { return *dir_ / rel; }
  static double ate_rmse(const std::string& args) {
    const auto r = run_program("cslam-eval", "ate " + args + " --json");
    EXPECT_EQ(r.status, 0) << r.output;
    return nlohmann::json::parse(r.output)["rmse"].get<double>();
  }
  static TempDir* dir_;
};
TempDir* SlamIntegration::dir_ = nullptr;

}  // namespace

TEST_F(SlamIntegration, SingleClientTracksEveryFrameWithinBound) {
  const auto r = run_program("cslam-slam", "--dataset " + scene("robot_1") + " --out " + tmp("traj.txt") +
                                               " --keyframes " + tmp("kf.txt") + " --stats " + tmp("stats.json") +
                                               " --sync --quiet --log-level warn");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto stats = nlohmann::json::parse(std::ifstream(tmp("stats.json")));
  EXPECT_EQ(stats["frames"].get<int>(), 60);
  EXPECT_EQ(stats["frames_lost"].get<int>(), 0);
  EXPECT_EQ(stats["trajectory_poses"].get<int>(), 60);
  EXPECT_GE(stats["keyframes"].get<int>(), 3);
  // Exact depth and textures: the camera path is recovered to a few millimetres.
  EXPECT_LT(ate_rmse(scene("robot_1/groundtruth.txt") + " " + tmp("traj.txt")), 0.015);
}

// Stepped (--sync): deterministic, so the accuracy bound is checked on the one possible outcome.
TEST_F(SlamIntegration, OfflineTwoClientsFuseIntoOneFrame) {
  const auto r = run_program("cslam-slam", "--datasets " + scene("robot_1") + " " + scene("robot_2") + " --out-dir " +
                                               tmp("multi") + " --sync --log-level warn");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto stats = nlohmann::json::parse(std::ifstream(tmp("multi/stats.json")));
  ASSERT_EQ(stats["clients"].size(), 2u);
  EXPECT_EQ(stats["clients"][0]["group"], stats["clients"][1]["group"]) << stats.dump(2);
  EXPECT_TRUE(stats["clients"][0]["fused"].get<bool>());
  ASSERT_GE(stats["fusion_events"].size(), 1u);
  // Both clients in one frame: one alignment for both trajectories keeps the error small.
  const double joint = ate_rmse(scene("robot_1/groundtruth.txt") + " " + tmp("multi/client_1.txt") + " --also " +
                                scene("robot_2/groundtruth.txt") + " " + tmp("multi/client_2.txt"));
  EXPECT_LT(joint, 0.02);
  EXPECT_TRUE(
      std::ifstream(tmp("multi/fused_" + std::to_string(stats["clients"][0]["group"].get<int>()) + ".txt")).good());
}

// The lean stream simulated per client (--depth-every): light frames between full ones, full depth
// when tracking asks (the server's depth requests), and the clients still fuse accurately.
TEST_F(SlamIntegration, OfflineTwoLeanClientsFuse) {
  const auto r = run_program("cslam-slam", "--datasets " + scene("robot_1") + " " + scene("robot_2") + " --out-dir " +
                                               tmp("lean") + " --sync --depth-every 5 --log-level warn");
  ASSERT_EQ(r.status, 0) << r.output;
  for (int k = 1; k <= 2; ++k) {
    const std::string tag = "client " + std::to_string(k) + ": light frames ";
    const auto at = r.output.find(tag);
    ASSERT_NE(at, std::string::npos) << r.output;
    const int light = std::stoi(r.output.substr(at + tag.size()));
    EXPECT_GT(light, 0) << r.output;
    EXPECT_LE(light, 48) << r.output;  // 60 frames, every 5th full
  }
  const auto stats = nlohmann::json::parse(std::ifstream(tmp("lean/stats.json")));
  ASSERT_EQ(stats["clients"].size(), 2u);
  EXPECT_EQ(stats["clients"][0]["group"], stats["clients"][1]["group"]) << stats.dump(2);
  const double joint = ate_rmse(scene("robot_1/groundtruth.txt") + " " + tmp("lean/client_1.txt") + " --also " +
                                scene("robot_2/groundtruth.txt") + " " + tmp("lean/client_2.txt"));
  EXPECT_LT(joint, 0.02);
}

// The threaded system (worker, local-mapping, loop and fusion threads) fuses the same robots; its
// accuracy is checked by the stepped run above and measured by scripts/bench-accuracy.sh.
TEST_F(SlamIntegration, ThreadedTwoClientsFuse) {
  const auto r = run_program("cslam-slam", "--datasets " + scene("robot_1") + " " + scene("robot_2") + " --out-dir " +
                                               tmp("threaded") + " --log-level warn");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto stats = nlohmann::json::parse(std::ifstream(tmp("threaded/stats.json")));
  ASSERT_EQ(stats["clients"].size(), 2u);
  EXPECT_EQ(stats["clients"][0]["group"], stats["clients"][1]["group"]) << stats.dump(2);
  EXPECT_EQ(stats["clients"][0]["trajectory_poses"].get<int>(), 60);
  EXPECT_EQ(stats["clients"][1]["trajectory_poses"].get<int>(), 60);
}

static std::string file_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// --sync is the threaded system's policy stepped on one thread: the same input gives the same
// bytes, for one client and for two clients with map fusion.
TEST_F(SlamIntegration, SyncRunsAreIdentical) {
  for (const char* run : {"a", "b"}) {
    const std::string single = tmp(std::string("single_") + run + ".txt");
    auto r = run_program("cslam-slam",
                         "--dataset " + scene("robot_1") + " --out " + single + " --sync --quiet --log-level warn");
    ASSERT_EQ(r.status, 0) << r.output;
    r = run_program("cslam-slam", "--datasets " + scene("robot_1") + " " + scene("robot_2") + " --out-dir " +
                                      tmp(std::string("pair_") + run) + " --sync --log-level warn");
    ASSERT_EQ(r.status, 0) << r.output;
  }
  const std::string a = file_text(tmp("single_a.txt"));
  EXPECT_GT(a.size(), 1000u);
  EXPECT_EQ(a, file_text(tmp("single_b.txt")));
  for (const char* f : {"client_1.txt", "client_2.txt"}) {
    const std::string pa = file_text(tmp("pair_a/") + f);
    EXPECT_GT(pa.size(), 1000u) << f;
    EXPECT_EQ(pa, file_text(tmp("pair_b/") + f)) << f;
  }
}

// Threaded, with tracking waiting until local mapping has processed each new keyframe (the
// default), every frame is tracked against the map --sync tracks it against: the same bytes. Without
// the wait, tracking runs ahead of local mapping and the output depends on thread timing.
TEST_F(SlamIntegration, ThreadedRunWaitingForEachKeyframeEqualsSync) {
  const std::string sync = tmp("wait_sync.txt");
  auto r = run_program("cslam-slam",
                       "--dataset " + scene("robot_1") + " --out " + sync + " --sync --quiet --log-level warn");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string expected = file_text(sync);
  ASSERT_GT(expected.size(), 1000u);
  for (const char* run : {"a", "b", "c"}) {
    const std::string out = tmp(std::string("wait_threaded_") + run + ".txt");
    r = run_program("cslam-slam", "--dataset " + scene("robot_1") + " --out " + out + " --quiet --log-level warn");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(file_text(out), expected) << "threaded run " << run;
  }
}

TEST_F(SlamIntegration, OfflineTwoClientsWithoutFusionStayApart) {
  const auto r = run_program("cslam-slam", "--datasets " + scene("robot_1") + " " + scene("robot_2") + " --out-dir " +
                                               tmp("apart") + " --no-fusion --log-level warn");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto stats = nlohmann::json::parse(std::ifstream(tmp("apart/stats.json")));
  EXPECT_NE(stats["clients"][0]["group"], stats["clients"][1]["group"]);
  EXPECT_EQ(stats["fusion_events"].size(), 0u);
  // Each client's own frame starts at its first camera: a joint alignment cannot fit both.
  const double joint = ate_rmse(scene("robot_1/groundtruth.txt") + " " + tmp("apart/client_1.txt") + " --also " +
                                scene("robot_2/groundtruth.txt") + " " + tmp("apart/client_2.txt"));
  EXPECT_GT(joint, 0.05);
}

TEST_F(SlamIntegration, ClientsInDifferentRoomsDoNotFuse) {
  // Two rooms (different seeds): same procedural texture style, different places, and the same
  // poster on the long walls of both (--shared-poster), plus a patch repeated inside each room.
  // A wrong fusion is worse than none, so nothing may be fused here.
  for (const char* room : {"room_a --seed 3", "room_b --seed 11"}) {
    const std::string name = std::string(room).substr(0, 6);
    auto r =
        run_program("cslam-synth", "--preset test-small --seed " + std::string(room).substr(14) +
                                       " --shared-poster 77 --repeat-texture --out " + tmp(name) + " --log-level warn");
    ASSERT_EQ(r.status, 0) << r.output;
  }
  // Clients 1, 3: robots of room a; clients 2, 4: robots of room b. Each room's robots share places.
  auto r = run_program("cslam-slam", "--datasets " + tmp("room_a/robot_1") + " " + tmp("room_b/robot_1") + " " +
                                         tmp("room_a/robot_2") + " " + tmp("room_b/robot_2") + " --out-dir " +
                                         tmp("rooms") + " --log-level warn");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto stats = nlohmann::json::parse(std::ifstream(tmp("rooms/stats.json")));
  for (const auto& e : stats["fusion_events"])
    EXPECT_EQ(e["client_a"].get<int>() % 2, e["client_b"].get<int>() % 2) << "fused across rooms: " << e.dump();
  const auto& c = stats["clients"];
  EXPECT_NE(c[0]["group"], c[1]["group"]);
  EXPECT_NE(c[0]["group"], c[3]["group"]);
  EXPECT_NE(c[2]["group"], c[1]["group"]);
  EXPECT_NE(c[2]["group"], c[3]["group"]);
  // The control: within each room the robots do fuse.
  EXPECT_EQ(c[0]["group"], c[2]["group"]);
  EXPECT_EQ(c[1]["group"], c[3]["group"]);
}

// The lens is covered for longer than max_lost_seconds (3 s), then the robot retraces its path:
// tracking starts a second map, map fusion joins it to the first, and cslam-slam writes the
// frames of both maps in one frame. --sync: the one possible outcome.
TEST_F(SlamIntegration, SingleClientLongLossSecondMapIsJoinedAndWritten) {
  const cslam::TumDataset ds = cslam::open_tum_dataset(scene("robot_1"));
  ASSERT_TRUE(ds.groundtruth);
  const std::string dir = tmp("covered");
  std::filesystem::create_directories(dir);
  std::filesystem::create_directory_symlink(scene("robot_1/rgb"), dir + "/rgb");
  std::filesystem::create_directory_symlink(scene("robot_1/depth"), dir + "/depth");
  std::filesystem::copy_file(scene("robot_1/camera.yaml"), dir + "/camera.yaml");
  const cv::Mat first = cv::imread(ds.pairs[0].rgb_path);
  ASSERT_FALSE(first.empty());
  ASSERT_TRUE(cv::imwrite(dir + "/black.png", cv::Mat(first.size(), CV_8UC3, cv::Scalar(0, 0, 0))));
  ASSERT_TRUE(cv::imwrite(dir + "/empty.png", cv::Mat(first.size(), CV_16UC1, cv::Scalar(0))));
  auto rel = [](const std::string& path) {
    const std::filesystem::path p(path);
    return (p.parent_path().filename() / p.filename()).string();
  };
  auto gt_at = [&](double t) {
    for (const auto& g : *ds.groundtruth)
      if (std::abs(g.timestamp - t) < 1e-6) return g.T_world_cam;
    ADD_FAILURE() << "no ground truth at " << t;
    return cslam::SE3();
  };
  std::ofstream rgb(dir + "/rgb.txt"), depth(dir + "/depth.txt");
  rgb.precision(17);
  depth.precision(17);
  cslam::Trajectory gt;
  std::size_t real = 0;
  double t = 0;
  for (std::size_t i = 0; i < 40; ++i, ++real) {  // frames 1-40
    t = ds.pairs[i].rgb_time;
    rgb << t << " " << rel(ds.pairs[i].rgb_path) << "\n";
    depth << t << " " << rel(ds.pairs[i].depth_path) << "\n";
    gt.push_back({t, gt_at(t)});
  }
  for (int k = 0; k < 15; ++k) {  // 3.5 s of covered lens
    t += 0.25;
    rgb << t << " black.png\n";
    depth << t << " empty.png\n";
  }
  const double shift = t + 0.25 - ds.pairs[10].rgb_time;
  for (std::size_t i = 10; i < ds.pairs.size(); ++i, ++real) {  // frames 11-60 again
    rgb << ds.pairs[i].rgb_time + shift << " " << rel(ds.pairs[i].rgb_path) << "\n";
    depth << ds.pairs[i].rgb_time + shift << " " << rel(ds.pairs[i].depth_path) << "\n";
    gt.push_back({ds.pairs[i].rgb_time + shift, gt_at(ds.pairs[i].rgb_time)});
  }
  rgb.close();
  depth.close();
  cslam::write_tum_trajectory(dir + "/groundtruth.txt", gt);

  for (const bool fusion : {true, false}) {
    SCOPED_TRACE(fusion ? "fusion" : "--no-fusion");
    const std::string out = tmp(fusion ? "loss_fused" : "loss_apart");
    const auto r = run_program("cslam-slam", "--dataset " + dir + " --out " + out + ".txt --stats " + out + ".json" +
                                                 " --sync --quiet --log-level warn" + (fusion ? "" : " --no-fusion"));
    ASSERT_EQ(r.status, 0) << r.output;
    const auto stats = nlohmann::json::parse(std::ifstream(out + ".json"));
    EXPECT_EQ(stats["maps"].get<int>(), 2) << "the covered stretch must start a second map";
    const int poses = stats["trajectory_poses"].get<int>();
    std::printf("%s: %d poses of %zu real frames, %d map fusions\n", fusion ? "fusion" : "--no-fusion", poses, real,
                stats["map_fusions"].get<int>());
    if (fusion) {
      EXPECT_EQ(stats["map_fusions"].get<int>(), 1);
      EXPECT_GE(poses + 2, int(real)) << "both maps' frames are written";
      const double ate = ate_rmse(dir + "/groundtruth.txt " + out + ".txt");
      std::printf("ATE %.4f m\n", ate);
      EXPECT_LT(ate, 0.02) << "in one frame";
    } else {
      EXPECT_EQ(stats["map_fusions"].get<int>(), 0);
      EXPECT_LT(poses, int(real) - 20) << "two frames: only the larger map is written";
    }
  }
}

TEST_F(SlamIntegration, BadArgumentsGiveOneLineErrors) {
  auto r = run_program("cslam-slam", "--dataset /nonexistent --out " + tmp("x.txt"));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("/nonexistent"), std::string::npos) << r.output;
  r = run_program("cslam-slam",
                  "--dataset " + scene("robot_1") + " --out " + tmp("x.txt") + " --vocab /nonexistent.voc");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("nonexistent.voc"), std::string::npos) << r.output;
}

namespace {

// Pose of the nearest ground-truth sample.
cslam::SE3 gt_at(const cslam::Trajectory& gt, double t) {
  const cslam::StampedPose* best = &gt.front();
  for (const auto& p : gt)
    if (std::abs(p.timestamp - t) < std::abs(best->timestamp - t)) best = &p;
  return best->T_world_cam;
}

}  // namespace

// A looping robot in a room with a deliberately repeated wall patch: the real loop is closed and
// no accepted loop is wrong (every loop's verified transform within 2 deg / 5 cm of ground truth).
TEST(LoopClosingIntegration, ClosesTheRealLoopAndIsNotFooledByRepeatedTexture) {
  TempDir dir("cslam_loop_it");
  auto r =
      run_program("cslam-synth", "--single --frames 290 --width 320 --height 240 --repeat-texture --seed 4 --out " +
                                     (dir / "scene") + " --log-level warn");
  ASSERT_EQ(r.status, 0) << r.output;
  // --sync: local mapping and loop closing inline, so the keyframes (and the loop) do not depend on
  // how busy the machine is (threaded, a loaded CI machine makes fewer keyframes near the end).
  r = run_program("cslam-slam", "--dataset " + (dir / "scene/robot_1") + " --out " + (dir / "loop.txt") + " --stats " +
                                    (dir / "loop.json") + " --sync --quiet --log-level warn");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto stats = nlohmann::json::parse(std::ifstream(dir / "loop.json"));
  const auto gt = cslam::read_tum_trajectory(dir / "scene/robot_1/groundtruth.txt");
  ASSERT_GE(stats["loop_events"].size(), 1u) << "the loop back to the start was not closed";
  for (const auto& l : stats["loop_events"]) {
    std::istringstream line(l["T_query_candidate"].get<std::string>());
    double v[8];
    for (double& x : v) line >> x;
    const cslam::SE3 est(Eigen::Quaterniond(v[7], v[4], v[5], v[6]), Eigen::Vector3d(v[1], v[2], v[3]));
    const cslam::SE3 truth = gt_at(gt, l["query_timestamp"]).inverse() * gt_at(gt, l["candidate_timestamp"]);
    const cslam::SE3 err = truth.inverse() * est;
    EXPECT_LT(err.rotation_angle() * 180 / M_PI, 2.0) << l.dump();
    EXPECT_LT(err.translation().norm(), 0.05) << l.dump();
  }
}
