#include <cmath>

#include <gtest/gtest.h>

#include "eval/split.h"

using namespace cslam;

TEST(Split, TwoClientsMatchPaperFormula) {
  const int N = 1800;
  const double eta = 0.05;
  const auto r = split_sequence(N, 2, eta);
  const double L = N / 2.0;
  const double delta = eta * L / (1 - eta / 2.0);
  EXPECT_NEAR(r.delta, delta, 1e-9);
  ASSERT_EQ(r.ranges.size(), 2u);
  EXPECT_EQ(r.ranges[0].first, 1);
  EXPECT_EQ(r.ranges[0].last, std::lround(N / 2.0 + delta / 2));
  EXPECT_EQ(r.ranges[1].first, std::lround(N / 2.0 - delta / 2));
  EXPECT_EQ(r.ranges[1].last, N);
  // The overlap rate definition holds: eta = delta / (L + (K-1) delta / K).
  EXPECT_NEAR(r.delta / (L + r.delta / 2), eta, 1e-12);
}

TEST(Split, ThreeClientsMatchPaperFormula) {
  for (double eta : {0.005, 0.025, 0.05, 0.10}) {
    const int N = 694;
    const auto r = split_sequence(N, 3, eta);
    const double L = N / 3.0;
    const double d = eta * L / (1 - eta * 2.0 / 3.0);
    EXPECT_NEAR(r.delta / (L + 2 * r.delta / 3), eta, 1e-12);
    ASSERT_EQ(r.ranges.size(), 3u);
    EXPECT_EQ(r.ranges[0].first, 1);
    EXPECT_EQ(r.ranges[0].last, std::lround(N / 3.0 + 2 * d / 3));
    EXPECT_EQ(r.ranges[1].first, std::lround(N / 3.0 + 1 - d / 3));
    EXPECT_EQ(r.ranges[1].last, std::lround(2 * N / 3.0 + d / 3));
    EXPECT_EQ(r.ranges[2].first, std::lround(2 * N / 3.0 + 1 - 2 * d / 3));
    EXPECT_EQ(r.ranges[2].last, N);
    // Neighbours overlap by about delta frames.
    EXPECT_NEAR(r.ranges[0].last - r.ranges[1].first + 1, d, 1.5);
  }
}

TEST(Split, GeneralKAndBadInput) {
  const auto r = split_sequence(1000, 5, 0.1);
  ASSERT_EQ(r.ranges.size(), 5u);
  for (size_t k = 0; k + 1 < r.ranges.size(); ++k) EXPECT_LT(r.ranges[k + 1].first, r.ranges[k].last);
  EXPECT_EQ(r.ranges.back().last, 1000);
  EXPECT_THROW(split_sequence(10, 0, 0.1), std::invalid_argument);
  EXPECT_THROW(split_sequence(2, 3, 0.1), std::invalid_argument);
  EXPECT_THROW(split_sequence(100, 2, 1.5), std::invalid_argument);
}
