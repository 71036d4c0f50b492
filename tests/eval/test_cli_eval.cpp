// Runs the cslam-eval program as a user would.
#include <array>
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
