// Unit tests of the experiment harness: options, the configuration matrix, frame lookup, ground
// truth interpolation, the pose alignment of the clouds, aggregation and child processes.
#include <cmath>
#include <csignal>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "core/error.h"
#include "eval/split.h"
#include "experiment_config.h"
#include "machine_info.h"
#include "process.h"
#include "report_plots.h"
#include "report_writer.h"
#include "run_evaluation.h"

using namespace cslam;
using namespace cslam::experiment;

TEST(Options, OverlapsArePercent) {
  EXPECT_EQ(parse_overlaps("0.5,2.5,5,10"), (std::vector<double>{0.5, 2.5, 5, 10}));
  EXPECT_EQ(parse_overlaps(" 5% , 10"), (std::vector<double>{5, 10}));
  EXPECT_THROW(parse_overlaps("abc"), ConfigError);
  EXPECT_THROW(parse_overlaps("5,,10"), ConfigError);
  EXPECT_THROW(parse_overlaps("60"), ConfigError);
  EXPECT_THROW(parse_overlaps("-1"), ConfigError);
}

TEST(Options, RunModes) {
  EXPECT_EQ(parse_mode("offline"), RunMode::kOffline);
  EXPECT_EQ(parse_mode("network"), RunMode::kNetwork);
  EXPECT_EQ(parse_mode("live"), RunMode::kLive);
  EXPECT_STREQ(to_string(RunMode::kLive), "live");
  EXPECT_THROW(parse_mode("realtime"), ConfigError);
}

TEST(Options, ClientCounts) {
  EXPECT_EQ(parse_client_counts("3,1,2"), (std::vector<int>{1, 2, 3}));
  EXPECT_THROW(parse_client_counts("0"), ConfigError);
  EXPECT_THROW(parse_client_counts("1,1"), ConfigError);
  EXPECT_THROW(parse_client_counts("2x"), ConfigError);
  try {
    parse_client_counts("1,x");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'x'"), std::string::npos) << e.what();
  }
}

TEST(Matrix, SplitModeUsesThePapersRanges) {
  ExperimentOptions o;
  o.dataset = "/d";
  o.clients = {1, 2, 3};
  o.overlaps_percent = {0.5, 5};
  const auto m = build_matrix(o, {"/d"}, {694});
  ASSERT_EQ(m.size(), 5u);
  EXPECT_EQ(m[0].name, "single");
  EXPECT_EQ(m[0].specs.at(0).first, 1);
  EXPECT_EQ(m[0].specs.at(0).last, 694);
  EXPECT_EQ(m[1].name, "k2_eta0_5");
  EXPECT_EQ(m[4].name, "k3_eta5");
  const auto s = split_sequence(694, 3, 0.05);
  ASSERT_EQ(m[4].specs.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(m[4].specs[k].first, s.ranges[k].first);
    EXPECT_EQ(m[4].specs[k].last, s.ranges[k].last);
    EXPECT_EQ(m[4].specs[k].id, k + 1);
  }
  EXPECT_TRUE(m[4].split);
  EXPECT_DOUBLE_EQ(m[4].overlap_percent, 5.0);
}

TEST(Matrix, DatasetsModeRunsEachDatasetAloneAndTheFirstK) {
  ExperimentOptions o;
  o.datasets = {"/s/robot_1", "/s/robot_2", "/s/robot_3"};
  o.clients = {1, 3};
  const auto m = build_matrix(o, o.datasets, {300, 280, 290});
  ASSERT_EQ(m.size(), 4u);
  EXPECT_EQ(m[1].name, "single_robot_2");
  EXPECT_EQ(m[1].label, "single (robot_2)");
  EXPECT_EQ(m[1].specs.at(0).last, 280);
  EXPECT_EQ(m[3].name, "k3");
  EXPECT_FALSE(m[3].split);
  EXPECT_TRUE(std::isnan(m[3].overlap_percent));
  o.clients = {4};
  EXPECT_THROW(build_matrix(o, o.datasets, {300, 280, 290}), ConfigError);
}

namespace {

TumDataset fake_dataset(int n, double t0 = 100.0) {
  TumDataset d;
  for (int i = 0; i < n; ++i) {
    RgbdPair p;
    p.rgb_time = t0 + i / 30.0;
    p.index = i;
    d.pairs.push_back(p);
  }
  return d;
}

SE3 rot(double angle_deg, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
  return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(angle_deg * M_PI / 180.0, axis.normalized())), t);
}

}  // namespace

TEST(FrameLookup, PositionWithinTheClientsOwnFrames) {
  const TumDataset d = fake_dataset(100);
  EXPECT_EQ(frame_number_at(d, 1, 100, 100.0), 1);
  EXPECT_EQ(frame_number_at(d, 41, 100, 100.0 + 50 / 30.0 + 0.004), 11);  // frame 51 of the sequence = 11th of 41..100
  EXPECT_EQ(frame_number_at(d, 41, 100, 100.0 + 10 / 30.0), -1);          // before the client's range
  EXPECT_EQ(frame_number_at(d, 1, 100, 500.0), -1);
  EXPECT_EQ(frame_number_at(d, 1, 100, NAN), -1);
}

TEST(GroundTruthAt, InterpolatesBetweenSamplesAndSkipsGaps) {
  Trajectory gt;
  gt.push_back({10.0, rot(0, Eigen::Vector3d::UnitZ(), {0, 0, 0})});
  gt.push_back({10.1, rot(10, Eigen::Vector3d::UnitZ(), {1, 0, 0})});
  gt.push_back({20.0, rot(0, Eigen::Vector3d::UnitZ(), {5, 5, 5})});
  const Trajectory r = groundtruth_at(gt, {10.05, 10.11, 15.0, 19.99, 30.0});
  ASSERT_EQ(r.size(), 3u);  // 15.0 is in a gap, 30.0 after the end
  EXPECT_NEAR(r[0].T_world_cam.translation().x(), 0.5, 1e-9);
  EXPECT_NEAR(r[0].T_world_cam.rotation_angle() * 180 / M_PI, 5.0, 1e-6);
  EXPECT_NEAR(r[1].T_world_cam.translation().x(), 1.0, 1e-9);  // nearest sample at the end of a run
  EXPECT_DOUBLE_EQ(r[1].timestamp, 10.11);
  EXPECT_NEAR(r[2].T_world_cam.translation().z(), 5.0, 1e-9);
}

// A camera turning in place (as on fr1/rpy): positions alone cannot fix the rotation of the
// alignment, positions plus orientations do.
TEST(PoseAlignment, RecoversTheRotationOfACameraTurningInPlace) {
  const SE3 T_gt_est = rot(30, {1, 2, 3}, {0.5, -1.0, 2.0});
  Trajectory gt, est;
  for (int i = 0; i < 100; ++i) {
    const double t = i * 0.1;
    const SE3 pose = SE3(rot(20 * std::sin(t), Eigen::Vector3d::UnitY(), Eigen::Vector3d::Zero())) *
                     rot(10 * std::cos(1.3 * t), Eigen::Vector3d::UnitX(),
                         {0.01 * std::sin(3 * t), 0.01 * std::cos(2 * t), 0.002 * t});
    gt.push_back({t, pose});
    est.push_back({t, T_gt_est.inverse() * pose});
  }
  const Sim3 S = pose_alignment({{gt, est}});
  const SE3 err = SE3(S.rotation(), S.translation()).inverse() * T_gt_est;
  EXPECT_LT(err.rotation_angle() * 180 / M_PI, 1e-6);
  EXPECT_LT(err.translation().norm(), 1e-6);
  EXPECT_THROW(pose_alignment({{gt, Trajectory{}}}), InputError);
}

TEST(Plots, RollPitchYaw) {
  const Rpy r = roll_pitch_yaw_deg(SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                                                          Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitY()) *
                                                          Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX())),
                                       Eigen::Vector3d::Zero()));
  EXPECT_NEAR(r.yaw, 0.3 * 180 / M_PI, 1e-9);
  EXPECT_NEAR(r.pitch, -0.2 * 180 / M_PI, 1e-9);
  EXPECT_NEAR(r.roll, 0.1 * 180 / M_PI, 1e-9);
}

TEST(Plots, RotationVector) {
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 2, 2).normalized()));
  const Eigen::Vector3d v = rotation_vector_deg(q);
  EXPECT_NEAR(v.norm(), 0.5 * 180 / M_PI, 1e-9);
  EXPECT_NEAR(v.x() * 2, v.y(), 1e-9);
  // q and -q are the same rotation
  EXPECT_NEAR((rotation_vector_deg(Eigen::Quaterniond(-q.coeffs())) - v).norm(), 0.0, 1e-9);
  EXPECT_NEAR(rotation_vector_deg(Eigen::Quaterniond::Identity()).norm(), 0.0, 1e-12);
}

TEST(Summaries, MedianRunIsShownAndTimeIsRelativeToSingle) {
  RunConfig single, two;
  single.name = "single";
  single.clients = 1;
  single.split = two.split = true;  // one sequence split: the baseline is the whole-sequence run
  two.name = "k2_eta5";
  two.clients = 2;
  two.overlap_percent = 5;
  std::vector<RunRecord> rec(5);
  const double times[] = {10, 12, 6, 5, 7}, rmse[] = {0.02, 0.03, 0.05, 0.01, 0.03};
  for (int i = 0; i < 5; ++i) {
    rec[i].config = i < 2 ? "single" : "k2_eta5";
    rec[i].repeat = i < 2 ? i + 1 : i - 1;
    rec[i].ok = true;
    rec[i].slam_time_s = times[i];
    rec[i].ate.rmse = rmse[i];
  }
  rec[2].ok = false;  // a failed run counts in neither median
  const auto s = summarize({single, two}, rec);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[1].ok, 2);
  EXPECT_EQ(s[1].runs.size(), 3u);
  EXPECT_NEAR(s[1].time_ratio, 6.0 / 11.0, 1e-12);
  EXPECT_NEAR(s[0].time_ratio, 1.0, 1e-12);
  ASSERT_NE(s[1].representative, nullptr);
  EXPECT_EQ(s[1].representative->ate.rmse, 0.01);  // lower median of {0.01, 0.03}
}

TEST(Summaries, TimeRatioPrefersRunsWithoutOtherLoad) {
  RunConfig single, two, three;
  single.split = two.split = three.split = true;
  single.name = "single";
  two.name = "k2";
  two.clients = 2;
  three.name = "k3";
  three.clients = 3;
  struct Row {
    const char* config;
    double time, other;
  };
  const Row rows[] = {{"single", 10, 0.0}, {"single", 20, 0.9}, {"k2", 8, 0.1},
                      {"k2", 18, 0.9},     {"k3", 16, 0.8},     {"k3", 14, 0.9}};
  std::vector<RunRecord> rec;
  for (const auto& r : rows) {
    RunRecord x;
    x.config = r.config;
    x.ok = true;
    x.slam_time_s = r.time;
    x.other_cpu_cores = r.other;
    rec.push_back(x);
  }
  const auto s = summarize({single, two, three}, rec);
  EXPECT_NEAR(s[1].time_ratio, 0.8, 1e-12);  // quiet runs: 8 / 10
  EXPECT_TRUE(s[1].time_ratio_quiet);
  EXPECT_NEAR(s[2].time_ratio, 15.0 / 15.0, 1e-12);  // no quiet k3 run: all runs, 15 / 15
  EXPECT_FALSE(s[2].time_ratio_quiet);
  EXPECT_TRUE(is_quiet(rec[2]));
  EXPECT_FALSE(is_quiet(rec[1]));
}

TEST(Summaries, DatasetsModeBaselineIsTheSingleRunsOfTheSameDatasets) {
  std::vector<RunConfig> configs(4);
  for (int d = 0; d < 3; ++d) {
    configs[d].name = "single_robot_" + std::to_string(d + 1);
    configs[d].specs = {{1, "/s/robot_" + std::to_string(d + 1), 1, 300}};
  }
  configs[3].name = "k2";
  configs[3].clients = 2;
  configs[3].specs = {{1, "/s/robot_1", 1, 300}, {2, "/s/robot_2", 1, 300}};
  std::vector<RunRecord> rec(4);
  const double times[] = {7, 8, 100, 12};
  for (int i = 0; i < 4; ++i) {
    rec[i].config = configs[i].name;
    rec[i].ok = true;
    rec[i].slam_time_s = times[i];
    rec[i].other_cpu_cores = 0;
  }
  const auto s = summarize(configs, rec);
  EXPECT_NEAR(s[3].time_ratio, 12.0 / 15.0, 1e-12);  // robot_3's single run is not part of it
  EXPECT_TRUE(std::isnan(s[0].time_ratio) || std::abs(s[0].time_ratio - 1.0) < 1e-12);
}

TEST(Summaries, FusionTexts) {
  RunRecord r;
  ClientRecord a, b;
  a.id = 1;
  a.fused_at_frame = 330;
  b.id = 2;
  b.fused_at_frame = 12;
  r.client_records = {a, b};
  FusionRecord f;
  f.client_a = 2;
  f.client_b = 1;
  f.frame_a = 12;
  f.frame_b = 330;
  f.wall_time_s = 0.81;
  r.fusions = {f};
  EXPECT_EQ(fused_frames_text(r), "1:330;2:12");
  EXPECT_EQ(fusion_events_text(r), "c2@12<->c1@330 0.81s");
}

TEST(Process, ExitCodesSignalsAndDeadlines) {
  test::TempDir dir("cslam_exp_proc");
  {
    ChildProcess p({"/bin/sh", "-c", "echo first; echo last line; exit 3"}, dir / "a.log");
    EXPECT_EQ(wait_any({&p}, Clock::now() + std::chrono::seconds(20)), 0);
    EXPECT_FALSE(p.succeeded());
    EXPECT_EQ(p.status_text(), "exit code 3");
    EXPECT_EQ(log_tail(dir / "a.log", 1), "last line");
    EXPECT_EQ(log_tail(dir / "a.log", 2), "first | last line");
  }
  {
    ChildProcess slow({"/bin/sleep", "30"}, dir / "b.log");
    ChildProcess quick({"/bin/true"}, dir / "c.log");
    const auto start = Clock::now();
    EXPECT_EQ(wait_any({&slow, &quick}, start + std::chrono::seconds(20)), 1);
    EXPECT_TRUE(quick.succeeded());
    EXPECT_EQ(wait_any({&slow, &quick}, Clock::now() + std::chrono::milliseconds(200)), -1);
    EXPECT_TRUE(slow.running());
    stop_all({&slow, &quick}, 5.0);
    EXPECT_FALSE(slow.running());
    EXPECT_EQ(slow.status_text(), "killed by signal " + std::to_string(SIGTERM) + " (" + strsignal(SIGTERM) + ")");
    EXPECT_LT(std::chrono::duration<double>(Clock::now() - start).count(), 10.0);
  }
  {
    // A child that ignores SIGTERM is killed after the grace period.
    ChildProcess stubborn({"/bin/sh", "-c", "trap '' TERM; echo ready; exec sleep 30"}, dir / "d.log");
    const auto start = Clock::now();
    while (log_tail(dir / "d.log", 1) != "ready" && Clock::now() - start < std::chrono::seconds(10))
      std::this_thread::sleep_for(std::chrono::milliseconds(5));  // until the trap is set
    stop_all({&stubborn}, 0.3);
    EXPECT_FALSE(stubborn.running());
    EXPECT_NE(stubborn.status_text().find("signal 9"), std::string::npos) << stubborn.status_text();
    EXPECT_LT(std::chrono::duration<double>(Clock::now() - start).count(), 10.0);
  }
  EXPECT_THROW(ChildProcess({"/nonexistent/program"}, dir / "e.log"), std::runtime_error);
}

TEST(Machine, CpuAccountingSeesTheChildrensWork) {
  test::TempDir dir("cslam_exp_cpu");
  const CpuSample before = cpu_sample();
  {
    ChildProcess busy({"/bin/sh", "-c", "i=0; while [ $i -lt 300000 ]; do i=$((i+1)); done"}, dir / "busy.log");
    ASSERT_EQ(wait_any({&busy}, Clock::now() + std::chrono::seconds(60)), 0);
    EXPECT_TRUE(busy.succeeded());
  }
  const CpuSample after = cpu_sample();
  ASSERT_TRUE(before.valid && after.valid);
  EXPECT_GT(own_cpu_seconds(before, after), 0.05);
  const double other = other_cpu_cores(before, after);
  EXPECT_GE(other, 0.0);
  EXPECT_LE(other, machine_info().cores + 0.5);
}
