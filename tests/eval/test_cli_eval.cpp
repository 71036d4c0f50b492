// Runs the cslam-eval program as a user would.
#include <array>
#include <cstdio>
#include <memory>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/test_data.h"

namespace {
struct RunResult {
  int status;
  std::string output;
};
RunResult run(const std::string& args) {
  const std::string cmd = std::string(CSLAM_BIN_DIR) + "/cslam-eval " + args + " 2>&1";
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(cmd.c_str(), "r"), pclose);
  std::string out;
  std::array<char, 512> buf{};
  while (fgets(buf.data(), buf.size(), pipe.get())) out += buf.data();
  const int status = pclose(pipe.release());
  return {WEXITSTATUS(status), out};
}
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
