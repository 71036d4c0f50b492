// Map persistence over real processes on loopback: cslam-server with --state-dir is SIGKILLed in
// the middle of a two-robot synthetic run and restarted on the same folder; the clients resume by
// themselves. Also: a server refuses a damaged state folder unless --state-reset.
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/run_program.h"
#include "eval/trajectory_eval.h"
#include "io/tum_dataset.h"
#include "io/trajectory_io.h"
#include "network/net_test_util.h"
#include "proto/snapshot_adapter.h"
#include "proto/snapshot_file.h"

namespace cslam {
namespace {

const std::string kBin = CSLAM_BIN_DIR;

std::vector<std::string> server_args(const std::string& bind, const std::string& endpoint_file, const std::string& out,
                                     std::vector<std::string> extra) {
  std::vector<std::string> a = {
      kBin + "/cslam-server", "--bind", bind, "--endpoint-file", endpoint_file, "--out-dir", out, "--http", "off",
      "--log-interval",       "2"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

std::vector<std::string> client_args(const std::string& endpoint, int id, const std::string& dataset,
                                     const std::string& rate) {
  return {kBin + "/cslam-client",
          "--server",
          endpoint,
          "--id",
          std::to_string(id),
          "--dataset",
          dataset,
          "--rate",
          rate,
          "--reply-timeout",
          "3",
          "--rgb-codec",
          "png"};
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

double joint_ate(const std::string& scene, const std::string& out) {
  std::vector<std::pair<Trajectory, Trajectory>> pairs;
  for (int k = 1; k <= 2; ++k)
    pairs.emplace_back(read_tum_trajectory(scene + "/robot_" + std::to_string(k) + "/groundtruth.txt"),
                       read_tum_trajectory(out + "/client_" + std::to_string(k) + ".txt"));
  return compute_ate_joint(pairs, Alignment::kSE3, 0.02).stats.rmse;
}

class Persistence : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_dir_ = std::make_unique<test::ScratchDir>("persist_scene");
    scene_ = scene_dir_->path();
    const auto r = test::run_program("cslam-synth", "--preset test-small --frames 300 --seed 5 --overlap 0.3 --out " +
                                                        scene_ + "/scene --force --log-level warn");
    ASSERT_EQ(r.status, 0) << r.output;
    scene_ += "/scene";
  }
  static void TearDownTestSuite() { scene_dir_.reset(); }
  static std::string scene_;
  static std::unique_ptr<test::ScratchDir> scene_dir_;
};
std::string Persistence::scene_;
std::unique_ptr<test::ScratchDir> Persistence::scene_dir_;

TEST_F(Persistence, KilledServerRestartsFromItsSnapshotAndClientsResume) {
  const std::string rate = "20";  // 300 frames: at least 15 s per robot
  // Reference: the same two robots uninterrupted, stepped on one thread, robot by robot, frame by
  // frame (cslam-slam --sync: the same SLAM and fusion, one fixed interleaving). It gives the same
  // ATE every time; a streamed uninterrupted run gives it too on a quiet machine, and varies under
  // load (below).
  const test::ScratchDir ref_dir("persist_ref");
  const std::string& ref = ref_dir.path();
  {
    const auto r =
        test::run_program("cslam-slam", "--datasets " + scene_ + "/robot_1 " + scene_ + "/robot_2 --sync --out-dir " +
                                            ref + "/out --quiet --log-level warn");
    ASSERT_EQ(r.status, 0) << r.output;
  }
  const double ate_ref = joint_ate(scene_, ref + "/out");

  const test::ScratchDir run_dir("persist_kill");
  const std::string& run = run_dir.path();
  const std::string state = run + "/state";
  std::string endpoint;
  auto server = std::make_unique<test::ChildProcess>(
      server_args(
          "tcp://127.0.0.1:*", run + "/endpoint1", run + "/out1",
          {"--state-dir", state, "--snapshot-interval", "2", "--clients", "2", "--exit-when-done", "--deterministic"}),
      run + "/server1.log");
  {
    const auto e = test::wait_for_file_line(run + "/endpoint1", 30);
    ASSERT_TRUE(e) << "see " << run << "/server1.log";
    endpoint = *e;
  }
  test::ChildProcess c1(client_args(endpoint, 1, scene_ + "/robot_1", rate), run + "/client1.log");
  test::ChildProcess c2(client_args(endpoint, 2, scene_ + "/robot_2", rate), run + "/client2.log");
  std::this_thread::sleep_for(std::chrono::seconds(12));
  ASSERT_TRUE(std::filesystem::exists(snapshot::current_path(state))) << "no snapshot after 12 s";
  // The kill comes once the last snapshot holds the two robots fused (they meet about 8 s in; a
  // loaded machine may lag), so the restart always covers a fused group.
  auto fused_on_disk = [&] {
    const SystemState s = snapshot::read_file(snapshot::current_path(state));
    return s.clients.size() == 2 && s.clients[0].maps[0].group == s.clients[1].maps[0].group;
  };
  for (int i = 0; i < 40 && !fused_on_disk(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(250));
  server.reset();  // SIGKILL
  std::filesystem::copy_file(snapshot::current_path(state), run + "/at_kill.snapshot");
  server = std::make_unique<test::ChildProcess>(server_args(endpoint, run + "/endpoint2", run + "/out2",
                                                            {"--state-dir", state, "--snapshot-interval", "2",
                                                             "--clients", "2", "--exit-when-done", "--deterministic"}),
                                                run + "/server2.log");
  // The clients finish by themselves, and successfully: the frames the dead server had acked
  // after its last snapshot, and those in flight, are sent again from the clients' re-send buffers
  // (the resumed Welcome's last_seq says where the restored server stands).
  EXPECT_EQ(c1.wait(300), 0) << "see " << run << "/client1.log";
  EXPECT_EQ(c2.wait(300), 0) << "see " << run << "/client2.log";
  ASSERT_EQ(server->wait(120), 0) << "see " << run << "/server2.log";
  for (int k = 1; k <= 2; ++k)
    EXPECT_NE(read_text(run + "/client" + std::to_string(k) + ".log").find("done, 300 frames"), std::string::npos)
        << "client " << k << " did not send every frame";
  EXPECT_NE(read_text(run + "/server2.log").find("restored"), std::string::npos);
  for (int k = 1; k <= 2; ++k)
    EXPECT_NE(read_text(run + "/client" + std::to_string(k) + ".log").find("resumed session"), std::string::npos)
        << "client " << k << " did not resume its session";

  // The robots met before the kill (fused about 8 s in): the snapshot holds their group's seams,
  // which hold the two maps together in the restored server's group BA and re-encounters.
  {
    const SystemState at_kill = snapshot::read_file(run + "/at_kill.snapshot");
    ASSERT_EQ(at_kill.clients.size(), 2u);
    if (at_kill.clients[0].maps[0].group == at_kill.clients[1].maps[0].group) {
      std::size_t links = 0;
      for (const auto& seam : at_kill.fusion.seams) links += seam.links.size();
      EXPECT_GE(links, 50u) << "the fused group's seams were not stored";
    } else {
      ADD_FAILURE() << "not fused at the kill: the test no longer covers a fused group's restart";
    }
  }

  // Every frame of the last snapshot is in the final trajectories, and so is every frame after
  // it: those the first server processed after its last snapshot were sent again.
  const auto r = test::run_program("cslam-map", "export-tum " + run + "/at_kill.snapshot -o " + run + "/at_kill");
  ASSERT_EQ(r.status, 0) << r.output;
  for (int k = 1; k <= 2; ++k) {
    const std::string id = std::to_string(k);
    const Trajectory before = read_tum_trajectory(run + "/at_kill/client_" + id + ".txt");
    const Trajectory after = read_tum_trajectory(run + "/out2/client_" + id + ".txt");
    ASSERT_FALSE(before.empty());
    std::set<double> final_times;
    for (const auto& p : after) final_times.insert(p.timestamp);
    std::size_t missing = 0;
    for (const auto& p : before) missing += !final_times.count(p.timestamp);
    EXPECT_EQ(missing, 0u) << "client " << k << ": frames of the last snapshot lost";
    const double t_snapshot = before.back().timestamp;
    auto first_after = final_times.upper_bound(t_snapshot);
    ASSERT_NE(first_after, final_times.end()) << "client " << k << ": nothing after the restart";
    const TumDataset ds = open_tum_dataset(scene_ + "/robot_" + id);
    std::size_t sent_after = 0, have_after = 0;
    for (const auto& pair : ds.pairs)
      if (pair.rgb_time >= *first_after) {
        ++sent_after;
        have_after += final_times.count(pair.rgb_time);
      }
    EXPECT_GE(double(have_after), 0.95 * double(sent_after)) << "client " << k << ": frames after the restart";
    EXPECT_EQ(after.size(), ds.pairs.size()) << "client " << k << ": every frame has a pose";
    EXPECT_NE(read_text(run + "/client" + id + ".log").find("sending"), std::string::npos)
        << "client " << k << " sent nothing again: the kill came right after a snapshot?";
  }
  const double ate = joint_ate(scene_, run + "/out2");
  RecordProperty("ate_uninterrupted_m", std::to_string(ate_ref));
  RecordProperty("ate_killed_m", std::to_string(ate));
  std::printf("joint ATE: uninterrupted %.4f m, killed and restarted %.4f m (ratio %.2f)\n", ate_ref, ate,
              ate / ate_ref);
  // The bound: 1.15 x the same run uninterrupted. The killed run's servers run
  // --deterministic (mapping and fusion inline on each client's worker), so only the interleaving
  // of the two robots' frames differs between runs, and it moves the uninterrupted run itself once
  // the server lags: streamed without a kill at d625bdc (docs/results/persistence_restart.md,
  // 2026-12-07), 0.0159 m in 8 of 8 quiet runs (the stepped value) but 0.0155-0.0226 m, median
  // 0.0186, in 12 runs under two busy loops (the fusion events are the same in every run; what
  // each robot has tracked when a group BA or a re-encounter correction lands differs): up to
  // 1.42 x the stepped reference. The bound is 1.15 x that upper end. Killed runs of the same
  // build: 0.0133-0.0158 m quiet (5), 0.0136-0.0221 m loaded (10). The factor was measured for
  // this SLAM on this scene, so the stepped reference must still be the one it was measured
  // against: a SLAM change that moves it needs the spread measured again, not a stale margin.
  // The restart's specific losses are checked exactly above (seams stored) and below (the
  // restored server's re-encounters are anchored by them).
  constexpr double kSteppedWhenMeasured = 0.0159, kStreamedSpread = 1.42;
  EXPECT_NEAR(ate_ref, kSteppedWhenMeasured, 0.05 * kSteppedWhenMeasured)
      << "the stepped reference moved: measure the streamed spread again (docs/results/persistence_restart.md)";
  const double uninterrupted_upper = kStreamedSpread * ate_ref;
  EXPECT_LE(ate, 1.15 * uninterrupted_upper) << "uninterrupted (stepped) " << ate_ref;
  const auto stats = nlohmann::json::parse(read_text(run + "/out2/stats.json"));
  for (const auto& e : stats["fusion_events"]) {
    if (e["kind"] == "reencounter") {
      EXPECT_GE(e["keyframes_kept"].get<int>(), 1) << "a re-encounter after the restart without the seams' anchors";
    }
  }
}

// Session 1 on one server run (then stopped), session 2 on a restarted server that loaded the
// snapshot of session 1. Returns the output folder of the second run.
struct Session {
  int id;
  std::string dataset, range, camera;
  std::vector<std::string> extra = {};  // more client options
};

// Runs the two sessions in the folder run; returns the second run's output folder.
std::string run_two_sessions(const std::string& run, const Session& s1, const Session& s2) {
  const std::string state = run + "/state";
  for (int k = 1; k <= 2; ++k) {
    const Session& s = k == 1 ? s1 : s2;
    const std::string n = std::to_string(k);
    // --deterministic: one client streams at a time, so every session's result depends only on its
    // frames, and the accuracy bounds below hold for the one possible outcome.
    test::ChildProcess server(
        server_args("tcp://127.0.0.1:*", run + "/endpoint" + n, run + "/out" + n,
                    {"--state-dir", state, "--clients", "1", "--exit-when-done", "--deterministic"}),
        run + "/server" + n + ".log");
    const auto endpoint = test::wait_for_file_line(run + "/endpoint" + n, 60);
    EXPECT_TRUE(endpoint) << "see " << run << "/server" << n << ".log";
    if (!endpoint) return run + "/out2";
    std::vector<std::string> args = client_args(*endpoint, s.id, s.dataset, "max");
    args.insert(args.end(), {"--range", s.range, "--camera", s.camera});
    args.insert(args.end(), s.extra.begin(), s.extra.end());
    test::ChildProcess client(args, run + "/client" + n + ".log");
    EXPECT_EQ(client.wait(600), 0) << "see " << run << "/client" << n << ".log";
    EXPECT_EQ(server.wait(300), 0) << "see " << run << "/server" << n << ".log";
  }
  return run + "/out2";
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// The group of each client in stats.json.
std::map<int, int> groups_of(const nlohmann::json& stats) {
  std::map<int, int> out;
  for (const auto& c : stats["clients"]) out[c["id"].get<int>()] = c["group"].get<int>();
  return out;
}

TEST(MultiSession, Fr1DeskSecondSessionIsFusedIntoTheLoadedMap) {
  const std::string desk = std::string(CSLAM_SHARED_DATA_DIR) + "/tum_fr1_desk";
  if (!std::filesystem::exists(desk + "/rgb.txt")) {
    const char* ci = std::getenv("CI");
    if (ci && std::string(ci) == "true") FAIL() << "real sequence missing: " << desk;
    GTEST_SKIP() << "real sequence not found at " << desk;
  }
  const test::ScratchDir run_dir("multisession_desk");
  const std::string out = run_two_sessions(run_dir.path(), {1, desk, "1:300", "tum1"}, {2, desk, "280:", "tum1"});
  const auto stats = read_json(out + "/stats.json");
  const auto groups = groups_of(stats);
  ASSERT_EQ(groups.size(), 2u) << stats.dump();
  EXPECT_EQ(groups.at(1), groups.at(2)) << "session 2 was not fused into session 1's map";
  const Trajectory gt = read_tum_trajectory(desk + "/groundtruth.txt");
  const Trajectory t1 = read_tum_trajectory(out + "/client_1.txt"), t2 = read_tum_trajectory(out + "/client_2.txt");
  EXPECT_GE(t1.size(), 280u) << "session 1 poses restored from the snapshot";
  EXPECT_GE(t2.size(), 250u);
  const double ate = compute_ate_joint({{gt, t1}, {gt, t2}}, Alignment::kSE3, 0.02).stats.rmse;
  // What the loaded map itself was worth: session 1 as the first server run left it.
  const std::string out1 = out.substr(0, out.size() - 1) + "1";
  const double ate_session1 =
      compute_ate(gt, read_tum_trajectory(out1 + "/client_1.txt"), Alignment::kSE3, 0.02).stats.rmse;
  std::printf("fr1/desk two sessions: combined ATE %.4f m (%zu + %zu poses); session 1 alone after run 1: %.4f m\n",
              ate, t1.size(), t2.size(), ate_session1);
  RecordProperty("ate_m", std::to_string(ate));
  RecordProperty("ate_session1_m", std::to_string(ate_session1));
  // Session 2 met session 1's map again after the fusion (re-encounters): that is what keeps it
  // from drifting away from the loaded map.
  int reencounters = 0;
  for (const auto& e : stats["fusion_events"]) reencounters += e["kind"] == "reencounter";
  EXPECT_GE(reencounters, 1) << stats["fusion_events"].dump();
  // The target: as accurate as three robots mapping the sequence at once (0.0147 m). The servers
  // run --deterministic, so this is the one possible outcome: 0.0116 m on the 2-core development
  // VM (0.0122 m with keypoints on whole pixels; 0.0185 m before re-encounters and before
  // snapshots kept rolling-shutter keypoints; each session alone 0.011 m). Threaded servers:
  // scripts/bench-sessions.sh, docs/persistence.md.
  EXPECT_LE(ate, 0.0147);
  EXPECT_LE(ate_session1, 0.015);
}

TEST_F(Persistence, TwoDaysSecondRobotStartsAwayAndMeetsTheLoadedMapLater) {
  // Day 1: robot 2's arc. Day 2 (a restarted server): robot 1, whose arc starts away from robot 2's
  // path and reaches it only in its last part.
  const test::ScratchDir run_dir("multisession_synth");
  const std::string out =
      run_two_sessions(run_dir.path(), {2, scene_ + "/robot_2", "1:", ""}, {1, scene_ + "/robot_1", "1:", ""});
  const auto stats = read_json(out + "/stats.json");
  const auto groups = groups_of(stats);
  ASSERT_EQ(groups.size(), 2u) << stats.dump();
  EXPECT_EQ(groups.at(1), groups.at(2)) << "day 2 was not fused into day 1's map";
  ASSERT_FALSE(stats["fusion_events"].empty());
  const TumDataset r1 = open_tum_dataset(scene_ + "/robot_1");
  const double start = r1.pairs.front().rgb_time, end = r1.pairs.back().rgb_time;
  const double when = stats["fusion_events"][0]["query_timestamp"].get<double>();
  const double fused_at = (when - start) / (end - start);
  std::printf("two days: fused at %.0f%% of day 2\n", 100 * fused_at);
  EXPECT_GT(fused_at, 0.3) << "robot 1 was expected to meet day 1's map only later";
  const double ate = joint_ate(scene_, out);
  std::printf("two days: combined ATE %.4f m\n", ate);
  // The servers run --deterministic: one outcome, 0.0230 m on the 2-core development VM since
  // strong corners are located inside their pixel (each robot alone 0.015-0.016 m: their drift
  // along arcs without loops bounds what any alignment of the two can reach). It was 0.0372-0.0377 m
  // with keypoints on whole pixels and 0.0555 m at its worst (docs/results/sessions.md). The bound
  // leaves 17 % above the measured outcome (it was 0.042, and 0.06 before that).
  EXPECT_LE(ate, 0.027);
}

TEST_F(Persistence, SameIdWithNewSessionStartsAMapThatFusionJoinsToTheLoadedOne) {
  const test::ScratchDir run_dir("multisession_sameid");
  const std::string out = run_two_sessions(run_dir.path(), {1, scene_ + "/robot_2", "1:", ""},
                                           {1, scene_ + "/robot_1", "1:", "", {"--new-session"}});
  const auto stats = read_json(out + "/stats.json");
  ASSERT_EQ(stats["clients"].size(), 1u) << stats.dump();
  EXPECT_EQ(stats["clients"][0]["maps"], 2) << "the new session should have started its own map";
  // One fusion joins the two maps (re-encounters between them may follow: other kinds).
  std::vector<nlohmann::json> fusions;
  for (const auto& e : stats["fusion_events"])
    if (e["kind"] == "fusion") fusions.push_back(e);
  ASSERT_EQ(fusions.size(), 1u) << "the two maps of client 1 were not fused: " << stats["fusion_events"].dump();
  EXPECT_EQ(fusions[0]["client_a"], 1);
  EXPECT_EQ(fusions[0]["client_b"], 1);
}

TEST_F(Persistence, DamagedStateFolderRefusesToStartUnlessReset) {
  const test::ScratchDir run_dir("persist_damaged");
  const std::string& run = run_dir.path();
  const std::string state = run + "/state";
  std::filesystem::create_directories(state);
  std::ofstream(snapshot::current_path(state)) << "CSLAMSNP but not really";
  test::ChildProcess refused(
      server_args("tcp://127.0.0.1:*", run + "/endpoint1", run + "/out1", {"--state-dir", state}),
      run + "/server1.log");
  const auto code = refused.wait(60);
  ASSERT_TRUE(code.has_value());
  EXPECT_NE(*code, 0);
  const std::string log = read_text(run + "/server1.log");
  EXPECT_NE(log.find(snapshot::current_path(state)), std::string::npos) << log;
  EXPECT_FALSE(std::filesystem::exists(run + "/endpoint1")) << "it started anyway";

  test::ChildProcess reset(server_args("tcp://127.0.0.1:*", run + "/endpoint2", run + "/out2",
                                       {"--state-dir", state, "--state-reset", "--no-slam"}),
                           run + "/server2.log");
  EXPECT_TRUE(test::wait_for_file_line(run + "/endpoint2", 30)) << read_text(run + "/server2.log");
  reset.terminate();
  EXPECT_EQ(reset.wait(60), 0);
}

}  // namespace
}  // namespace cslam
