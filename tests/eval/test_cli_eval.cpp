// Runs the cslam-eval program as a user would.
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/run_program.h"
#include "common/test_data.h"

namespace {
cslam::test::RunResult run(const std::string& args) { return cslam::test::run_program("cslam-eval", args); }
}  // namespace

TEST(CslamEvalCli, AteOnRealGroundTruth) {
  CSLAM_REQUIRE_TUM_RPY();
  const std::string gt = cslam::test::tum_rpy_dir() + "/groundtruth.txt";
  const auto r = run("ate " + gt + " " + gt + " --json");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output);
  EXPECT_GT(j["n"].get<int>(), 2000);
  EXPECT_LT(j["rmse"].get<double>(), 1e-9);
}

TEST(CslamEvalCli, ErrorsAreOneLineAndNonZero) {
  auto r = run("ate /nonexistent/gt.txt /nonexistent/est.txt");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("/nonexistent/gt.txt"), std::string::npos) << r.output;
  r = run("split --frames 100 --clients 2");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("--overlap"), std::string::npos) << r.output;
  r = run("split --frames 694 --clients 2 --overlap 5%");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("client 2:"), std::string::npos) << r.output;
}

TEST(CslamEvalCli, EventsCheckLoopAndFusionTransformsAgainstGroundTruth) {
  cslam::test::TempDir dir("cslam_eval_events");
  // Ground truth: a camera moving along x and turning about z; two events measured on it, one
  // exact (loop of client 1) and one 3 degrees off (fusion of clients 2 and 1).
  {
    std::FILE* f = std::fopen((dir / "gt.txt").c_str(), "w");
    for (int i = 0; i <= 100; ++i) {
      const double t = i * 0.01, a = 0.5 * t;
      std::fprintf(f, "%.6f %.6f 0 0 0 0 %.9f %.9f\n", t, t, std::sin(a / 2), std::cos(a / 2));
    }
    std::fclose(f);
  }
  // p_query = T * p_candidate with T = T_world_q^-1 * T_world_c; query at t=0.8, candidate at t=0.2.
  auto rel = [](double tq, double tc, double extra_deg) {
    const double a = 0.5 * (tc - tq) + extra_deg * M_PI / 180;  // rotation about z
    const double aq = 0.5 * tq, dx = tc - tq;                   // translation: R_q^T (x_c - x_q)
    char buf[200];
    std::snprintf(buf, sizeof buf, "0 %.9f %.9f 0 0 0 %.9f %.9f", std::cos(aq) * dx, -std::sin(aq) * dx,
                  std::sin(a / 2), std::cos(a / 2));
    return std::string(buf);
  };
  nlohmann::json stats;
  stats["clients"] = {{{"id", 1},
                       {"loop_events",
                        {{{"query_timestamp", 0.8},
                          {"candidate_timestamp", 0.2},
                          {"inliers", 100},
                          {"T_query_candidate", rel(0.8, 0.2, 0)}}}}}};
  stats["fusion_events"] = {{{"client_a", 2},
                             {"client_b", 1},
                             {"query_timestamp", 0.6},
                             {"candidate_timestamp", 0.1},
                             {"inliers", 80},
                             {"T_query_candidate", rel(0.6, 0.1, 3.0)}}};
  {
    std::FILE* f = std::fopen((dir / "stats.json").c_str(), "w");
    std::fputs(stats.dump().c_str(), f);
    std::fclose(f);
  }
  const auto r = run("events " + (dir / "stats.json") + " --gt " + (dir / "gt.txt") + " --json");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output);
  ASSERT_EQ(j["events_total"].get<int>(), 2);
  EXPECT_EQ(j["events_within_bounds"].get<int>(), 1);
  EXPECT_EQ(j["events"][0]["kind"], "loop");
  EXPECT_LT(j["events"][0]["rotation_error_deg"].get<double>(), 1e-3);
  EXPECT_LT(j["events"][0]["translation_error_m"].get<double>(), 1e-6);
  EXPECT_EQ(j["events"][1]["kind"], "fusion");
  EXPECT_NEAR(j["events"][1]["rotation_error_deg"].get<double>(), 3.0, 1e-3);
  EXPECT_FALSE(j["events"][1]["within_bounds"].get<bool>());

  // A broken transform is a one-line error naming the file.
  stats["fusion_events"][0]["T_query_candidate"] = "0 1 2";
  {
    std::FILE* f = std::fopen((dir / "bad.json").c_str(), "w");
    std::fputs(stats.dump().c_str(), f);
    std::fclose(f);
  }
  const auto bad = run("events " + (dir / "bad.json") + " --gt " + (dir / "gt.txt"));
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.output.find("bad.json"), std::string::npos) << bad.output;
}
