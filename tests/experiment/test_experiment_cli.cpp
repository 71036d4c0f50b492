// cslam-experiment as a user runs it: --quick end to end (report, CSV, JSON, SVGs, sane numbers),
// the offline mode, a dataset without ground truth, failing runs, bad arguments.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/run_program.h"
#include "support/report/xml_check.h"

using cslam::test::run_program;
using cslam::test::TempDir;
namespace fs = std::filesystem;

namespace {

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// RFC 4180 rows (quoted fields may hold commas and newlines).
std::vector<std::vector<std::string>> parse_csv(const std::string& text) {
  std::vector<std::vector<std::string>> rows(1);
  std::string field;
  bool quoted = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"')
        field += text[++i];
      else if (c == '"')
        quoted = false;
      else
        field += c;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      rows.back().push_back(field);
      field.clear();
    } else if (c == '\n') {
      rows.back().push_back(field);
      field.clear();
      rows.emplace_back();
    } else {
      field += c;
    }
  }
  if (rows.back().empty()) rows.pop_back();
  return rows;
}

// Every report file exists and is well-formed; every SVG that report.md links exists.
void check_report_files(const std::string& out, std::size_t runs) {
  for (const char* f : {"report.md", "results.csv", "results.json"}) ASSERT_TRUE(fs::exists(out + "/" + f)) << f;
  const std::string md = slurp(out + "/report.md");
  EXPECT_NE(md.find("## Table II"), std::string::npos);
  EXPECT_NE(md.find("## Table III"), std::string::npos);
  EXPECT_NE(md.find("--out"), std::string::npos) << "the reproduce command is missing";
  int svgs = 0;
  for (const auto& e : fs::directory_iterator(out + "/figures")) {
    if (e.path().extension() != ".svg") continue;
    ++svgs;
    const std::string svg = slurp(e.path().string());
    EXPECT_EQ(cslam::test::xml_wellformed_error(svg), "") << e.path();
    EXPECT_EQ(svg.find("nan"), std::string::npos) << e.path();
  }
  EXPECT_GE(svgs, 1);
  for (std::size_t p = md.find("](figures/"); p != std::string::npos; p = md.find("](figures/", p + 1)) {
    const std::string rel = md.substr(p + 2, md.find(')', p) - p - 2);
    EXPECT_TRUE(fs::exists(out + "/" + rel)) << rel;
  }
  const auto rows = parse_csv(slurp(out + "/results.csv"));
  ASSERT_GE(rows.size(), 2u);
  const std::size_t width = rows[0].size();
  std::size_t run_rows = 0;
  for (const auto& r : rows) {
    EXPECT_EQ(r.size(), width);
    run_rows += !r.empty() && r[0] == "run";
  }
  EXPECT_EQ(run_rows, runs);
  const auto j = nlohmann::json::parse(slurp(out + "/results.json"));
  EXPECT_EQ(j["runs"].size(), runs);
}

double col(const nlohmann::json& run, const char* key) { return run[key].is_null() ? NAN : run[key].get<double>(); }

// One --quick run for the suite: its scene is reused by the other tests.
class ExperimentCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("cslam_experiment");
    quick_ = new cslam::test::RunResult(run_program("cslam-experiment", "--quick --out " + (*dir_ / "quick")));
  }
  static void TearDownTestSuite() {
    delete quick_;
    delete dir_;
  }
  static std::string path(const std::string& rel) { return *dir_ / rel; }
  static TempDir* dir_;
  static cslam::test::RunResult* quick_;
};
TempDir* ExperimentCli::dir_ = nullptr;
cslam::test::RunResult* ExperimentCli::quick_ = nullptr;

}  // namespace

TEST_F(ExperimentCli, QuickRunWritesAWellFormedReportWithSaneNumbers) {
  ASSERT_EQ(quick_->status, 0) << quick_->output;
  const std::string out = path("quick");
  // test-small: 2 robots -> single robot_1, single robot_2, 2 clients
  check_report_files(out, 3);
  EXPECT_TRUE(fs::exists(out + "/figures/k2_ape.svg"));
  EXPECT_TRUE(fs::exists(out + "/figures/k2_xy.svg"));
  EXPECT_TRUE(fs::exists(out + "/figures/k2_pose.svg"));
  EXPECT_TRUE(fs::exists(out + "/runs/k2/r1/server.log"));
  EXPECT_TRUE(fs::exists(out + "/runs/k2/r1/client_2.log"));
  const auto j = nlohmann::json::parse(slurp(out + "/results.json"));
  for (const auto& r : j["runs"]) {
    SCOPED_TRACE(r["config"].get<std::string>());
    EXPECT_EQ(r["status"], "ok") << r["error"];
    EXPECT_GT(col(r, "slam_time_s"), 0.0);
    EXPECT_LT(col(r, "slam_time_s"), 120.0);
    EXPECT_GT(col(r, "slam_cpu_s"), 0.0);
    EXPECT_GE(col(r, "other_cpu_cores"), 0.0);
    EXPECT_LT(col(r, "ate_rmse_m"), 0.05);  // exact synthetic data: millimetres in practice
    EXPECT_LE(col(r, "ate_min_m"), col(r, "ate_rmse_m"));
    EXPECT_LE(col(r, "ate_rmse_m"), col(r, "ate_max_m"));
    EXPECT_EQ(col(r, "frames_lost"), 0.0);
    EXPECT_LT(col(r, "hausdorff_bbox_m"), 0.5);
    EXPECT_LT(col(r, "scene_c2c_median_m"), 0.05);
    EXPECT_GT(col(r, "slam_cloud_points"), 1000.0);
  }
  const auto& k2 = j["runs"][2];
  EXPECT_EQ(k2["config"], "k2");
  EXPECT_TRUE(k2["all_fused"].get<bool>()) << k2.dump(2);
  ASSERT_GE(k2["fusion_events"].size(), 1u);
  for (const auto& c : k2["client_records"]) EXPECT_GT(c["fused_at_frame"].get<int>(), 0) << c.dump();
  EXPECT_GT(col(j["configs"][2], "slam_time_ratio_to_single"), 0.0);
  const std::string md = slurp(out + "/report.md");
  EXPECT_NE(md.find("| 2 clients |"), std::string::npos);
  EXPECT_NE(md.find("yes (1/1)"), std::string::npos) << md;
  EXPECT_NE(quick_->output.find("reproduce:"), std::string::npos);
}

TEST_F(ExperimentCli, OfflineModeOnTheSameScene) {
  ASSERT_EQ(quick_->status, 0) << quick_->output;
  const auto r = run_program("cslam-experiment", "--quick --mode offline --clients 2 --no-recon --synthetic " +
                                                     path("quick/synthetic_test-small") + " --out " + path("offline"));
  ASSERT_EQ(r.status, 0) << r.output;
  check_report_files(path("offline"), 1);
  const auto j = nlohmann::json::parse(slurp(path("offline/results.json")));
  EXPECT_EQ(j["runs"][0]["mode"], "offline");
  EXPECT_TRUE(j["runs"][0]["all_fused"].get<bool>());
  EXPECT_LT(col(j["runs"][0], "ate_rmse_m"), 0.05);
  EXPECT_TRUE(j["runs"][0]["hausdorff_bbox_m"].is_null());  // --no-recon
  EXPECT_NE(slurp(path("offline/report.md")).find("n/a: reconstruction off"), std::string::npos);
}

TEST_F(ExperimentCli, DatasetWithoutGroundTruthReportsTimingAndNa) {
  ASSERT_EQ(quick_->status, 0) << quick_->output;
  const std::string src = path("quick/synthetic_test-small/robot_1"), dst = path("nogt");
  fs::create_directories(dst);
  for (const char* f : {"rgb.txt", "depth.txt", "camera.yaml"}) fs::copy_file(src + "/" + f, dst + "/" + f);
  fs::create_directory_symlink(src + "/rgb", dst + "/rgb");
  fs::create_directory_symlink(src + "/depth", dst + "/depth");
  const auto r = run_program("cslam-experiment", "--quick --mode offline --dataset " + dst +
                                                     " --clients 1,2 --overlaps 20 --out " + path("nogt_report"));
  ASSERT_EQ(r.status, 0) << r.output;
  check_report_files(path("nogt_report"), 2);
  const auto j = nlohmann::json::parse(slurp(path("nogt_report/results.json")));
  for (const auto& run : j["runs"]) {
    EXPECT_EQ(run["status"], "ok") << run["error"];
    EXPECT_GT(col(run, "slam_time_s"), 0.0);
    EXPECT_TRUE(run["ate_rmse_m"].is_null());
    EXPECT_NE(run["ate_note"].get<std::string>().find("no ground truth"), std::string::npos);
  }
  const std::string md = slurp(path("nogt_report/report.md"));
  EXPECT_NE(md.find("**no ground truth**"), std::string::npos);
  EXPECT_NE(md.find("| n/a |"), std::string::npos);
}

TEST_F(ExperimentCli, FailingRunsAreReportedAndTheHarnessContinues) {
  ASSERT_EQ(quick_->status, 0) << quick_->output;
  // A stand-in cslam-slam that fails: every run fails with its exit code and last log line.
  const std::string bin = path("fakebin");
  fs::create_directories(bin);
  std::ofstream(bin + "/cslam-slam") << "#!/bin/sh\necho 'cslam-slam: error: disk on fire' >&2\nexit 7\n";
  fs::permissions(bin + "/cslam-slam", fs::perms::owner_all);
  auto r = run_program("cslam-experiment", "--quick --mode offline --bin-dir " + bin + " --synthetic " +
                                               path("quick/synthetic_test-small") + " --out " + path("failing"));
  EXPECT_EQ(r.status, 3) << r.output;
  check_report_files(path("failing"), 3);
  auto j = nlohmann::json::parse(slurp(path("failing/results.json")));
  for (const auto& run : j["runs"]) {
    EXPECT_EQ(run["status"], "failed");
    EXPECT_NE(run["error"].get<std::string>().find("exit code 7"), std::string::npos) << run["error"];
    EXPECT_NE(run["error"].get<std::string>().find("disk on fire"), std::string::npos) << run["error"];
  }
  EXPECT_NE(slurp(path("failing/report.md")).find("FAILED: cslam-slam"), std::string::npos);

  // A run over its time limit is stopped and reported; the next configuration still runs.
  r = run_program("cslam-experiment", "--quick --timeout 0.2 --no-recon --synthetic " +
                                          path("quick/synthetic_test-small") + " --out " + path("timeout"));
  EXPECT_EQ(r.status, 3) << r.output;
  j = nlohmann::json::parse(slurp(path("timeout/results.json")));
  ASSERT_EQ(j["runs"].size(), 3u);
  // Either the run itself overran ("timeout after ...") or its server had not even started.
  for (const auto& run : j["runs"])
    EXPECT_NE(run["error"].get<std::string>().find("timeout"), std::string::npos) << run["error"];
}

TEST_F(ExperimentCli, BadArgumentsGiveOneLineErrors) {
  struct Case {
    std::string args, expect;
  };
  const std::vector<Case> cases = {
      {"--out " + path("x"), "no data"},
      {"--quick --overlaps abc --out " + path("x"), "--overlaps"},
      {"--quick --clients 0 --out " + path("x"), "--clients"},
      {"--quick --mode fast --out " + path("x"), "--mode"},
      {"--quick --repeat 0 --out " + path("x"), "--repeat"},
      {"--quick --byte-budget -1 --out " + path("x"), "--byte-budget"},
      {"--dataset /nonexistent/seq --out " + path("x"), "/nonexistent/seq"},
      {"--dataset a --datasets b c --out " + path("x"), "only one of"},
      {"--quick --bin-dir /nonexistent --out " + path("x"), "/nonexistent/cslam-server"},
      {"--quick --clients 3 --synthetic " + path("quick/synthetic_test-small") + " --out " + path("x"), "only 2 given"},
      {"--quick", "--out"},
  };
  for (const auto& c : cases) {
    const auto r = run_program("cslam-experiment", c.args);
    EXPECT_NE(r.status, 0) << c.args;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << "\n" << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << c.args << "\n" << r.output;
  }
}
