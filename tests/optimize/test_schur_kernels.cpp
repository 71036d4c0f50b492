// The Schur complement's pair-product kernels against a plain triple loop: both implementations,
// random blocks, points seen by 1-12 of 20 cameras in any order, repeated calls accumulating into
// one matrix, and the upper block triangle left untouched.
#include <algorithm>
#include <numeric>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "core/cpu_features.h"
#include "optimize/schur_kernels.h"

namespace sk = cslam::schur_kernels;

namespace {

struct PointInput {
  std::vector<std::vector<double>> T, W;  // 6x3 column-major each
  std::vector<int> cam;
};

std::vector<PointInput> random_points(std::mt19937& rng, int cameras, int points) {
  std::uniform_real_distribution<double> value(-3.0, 3.0);
  std::vector<PointInput> out(static_cast<std::size_t>(points));
  std::vector<int> order(static_cast<std::size_t>(cameras));
  std::iota(order.begin(), order.end(), 0);
  for (PointInput& p : out) {
    std::shuffle(order.begin(), order.end(), rng);
    const int m = 1 + int(rng() % 12);
    for (int k = 0; k < m; ++k) {
      p.cam.push_back(order[std::size_t(k)]);
      p.T.emplace_back(18);
      p.W.emplace_back(18);
      for (double& x : p.T.back()) x = value(rng);
      for (double& x : p.W.back()) x = value(rng);
    }
  }
  return out;
}

// S(6 cam_i + r, 6 cam_j + c) -= sum_k T_i(r, k) W_j(c, k) for cam_j <= cam_i.
void reference(const PointInput& p, std::vector<double>& S, int ld) {
  for (std::size_t i = 0; i < p.cam.size(); ++i)
    for (std::size_t j = 0; j < p.cam.size(); ++j) {
      if (p.cam[j] > p.cam[i]) continue;
      for (int r = 0; r < 6; ++r)
        for (int c = 0; c < 6; ++c) {
          double sum = 0;
          for (int k = 0; k < 3; ++k) sum += p.T[i][std::size_t(6 * k + r)] * p.W[j][std::size_t(6 * k + c)];
          S[std::size_t((6 * p.cam[j] + c) * ld + 6 * p.cam[i] + r)] -= sum;
        }
    }
}

void run(sk::PairProductsFn fn, const PointInput& p, std::vector<double>& S, int ld) {
  std::vector<const double*> T, W;
  for (std::size_t i = 0; i < p.cam.size(); ++i) {
    T.push_back(p.T[i].data());
    W.push_back(p.W[i].data());
  }
  fn(T.data(), W.data(), p.cam.data(), int(p.cam.size()), S.data(), ld);
}

void expect_matches_reference(sk::PairProductsFn fn) {
  std::mt19937 rng(11);
  const int cameras = 20, ld = 6 * cameras;
  for (int trial = 0; trial < 20; ++trial) {
    const auto points = random_points(rng, cameras, 200);
    std::vector<double> start(std::size_t(ld) * ld);
    std::uniform_real_distribution<double> value(-10.0, 10.0);
    for (double& x : start) x = value(rng);
    std::vector<double> expected = start, got = start;
    for (const PointInput& p : points) {
      reference(p, expected, ld);
      run(fn, p, got, ld);
    }
    for (int col = 0; col < ld; ++col)
      for (int row = 0; row < ld; ++row) {
        const std::size_t k = std::size_t(col * ld + row);
        if (row / 6 < col / 6) {
          ASSERT_EQ(got[k], start[k]) << "upper block written at " << row << "," << col;
        } else {
          ASSERT_NEAR(got[k], expected[k], 1e-9 * (1.0 + std::abs(expected[k])))
              << row << "," << col << " trial " << trial;
        }
      }
  }
}

}  // namespace

TEST(SchurKernels, PortableMatchesReference) { expect_matches_reference(&sk::pair_products_portable); }

TEST(SchurKernels, Avx2MatchesReference) {
  if (!cslam::cpu_has_avx2_fma()) GTEST_SKIP() << "this CPU has no AVX2+FMA";
  expect_matches_reference(&sk::pair_products_avx2);
}

TEST(SchurKernels, DispatchPicksTheFastestAvailable) {
  EXPECT_EQ(sk::pair_products() == &sk::pair_products_avx2, cslam::cpu_has_avx2_fma());
  EXPECT_STREQ(sk::pair_products_isa(), cslam::cpu_has_avx2_fma() ? "avx2-fma" : "portable");
}
