#pragma once
// Locating the real TUM sequence for tests: ../shared/data beside the clone.
// Under CI (CI=true) a missing sequence is a failure, elsewhere the test is skipped loudly.
#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

namespace cslam::test {

inline std::string tum_rpy_dir() { return std::string(CSLAM_SHARED_DATA_DIR) + "/tum_fr1_rpy"; }

inline bool running_in_ci() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) != "" && std::string(ci) != "0" && std::string(ci) != "false";
}

}  // namespace cslam::test

// Use at the top of a test that needs the real sequence.
#define CSLAM_REQUIRE_TUM_RPY()                                                                            \
  do {                                                                                                     \
    if (!std::filesystem::exists(cslam::test::tum_rpy_dir() + "/rgb.txt")) {                               \
      if (cslam::test::running_in_ci()) FAIL() << "real sequence missing: " << cslam::test::tum_rpy_dir(); \
      GTEST_SKIP() << "real sequence not found at " << cslam::test::tum_rpy_dir();                         \
    }                                                                                                      \
  } while (0)
